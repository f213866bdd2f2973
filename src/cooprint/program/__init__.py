"""Program: what the robots execute. For now the G-code writer used by ``cooprint slice``; the
cooperative command stream (MOVE / TOOL / NOTIFY / WAIT) joins it here."""
