"""Subcommands of the floorsim CLI (see floorsim.cli).

A command's ``run`` imports the library modules it needs when it runs: ``floorsim --help``
and a mistyped flag answer at once, without loading Mitsuba, OpenCV and the bench. These
imports dodge no cycle (the command modules are leaves; each import works at module level
too).
"""
