"""Program (seed §4.2.2-4.3): what the robots execute.

``commands`` is the command language (MOVE / TOOL / NOTIFY / WAIT, with annotations) as a record,
a writer and a parser; ``build`` makes each robot's stream from the chunks' layers (transitions,
synchronisation) for the seed's one or two robots; ``fleet`` makes N robots' streams from a
schedule, guarded so that they are safe at any speeds; ``gcode`` writes any stream as Marlin G-code.
Both writers take a program piece by piece (``CoopWriter``, ``gcode.GcodeFile``), the same bytes for
any split, and format whole blocks of commands at once (``numtext``).
"""

from cooprint.program.commands import (MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT, CoopWriter, Program, ProgramError,
                                       coop_text, parse_coop, program_rows, read_coop, write_coop)

__all__ = ["MOVE", "NOTIFY", "TOOL_OFF", "TOOL_ON", "WAIT", "CoopWriter", "Program", "ProgramError", "coop_text",
           "parse_coop", "program_rows", "read_coop", "write_coop"]
