"""The `prehensile` command line (typer); see :mod:`prehensile.cli.main`."""
