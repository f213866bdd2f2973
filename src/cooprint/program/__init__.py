"""Program (seed §4.2.2-4.3): what the robots execute.

``commands`` is the command language (MOVE / TOOL / NOTIFY / WAIT, with annotations) as a record,
a writer and a parser; ``build`` makes each robot's stream from the chunks' layers (transitions,
synchronisation) for the seed's one or two robots; ``fleet`` makes N robots' streams from a
schedule, guarded so that they are safe at any speeds; ``gcode`` writes any stream as Marlin G-code.
"""

from cooprint.program.commands import (MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT, Program, ProgramError, coop_text,
                                       parse_coop, read_coop, write_coop)

__all__ = ["MOVE", "NOTIFY", "TOOL_OFF", "TOOL_ON", "WAIT", "Program", "ProgramError", "coop_text", "parse_coop",
           "read_coop", "write_coop"]
