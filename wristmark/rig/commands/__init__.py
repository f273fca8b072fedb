"""Subcommands of the wristmark command line, one module each (add_arguments + run)."""
