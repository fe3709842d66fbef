"""``python -m prehensile``: the command-line tool, as ``prehensile``."""

from prehensile.cli.main import app

app(prog_name="prehensile")
