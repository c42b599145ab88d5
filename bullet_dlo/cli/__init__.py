"""The ``bullet-dlo`` command line: one subcommand per task."""
from bullet_dlo.cli.main import main

__all__ = ["main"]
