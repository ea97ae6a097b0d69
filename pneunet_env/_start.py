"""Imported first by the package, for its effect: in the command line's process (``pneunet-grasp``), a Ctrl-C while
the package and the command's module are imported ends in the command's one line and exit status 130, not a
traceback (:func:`pneunet_env.files.command_line_interrupts`; elsewhere it does nothing)."""

from pneunet_env.files import command_line_interrupts

command_line_interrupts()
