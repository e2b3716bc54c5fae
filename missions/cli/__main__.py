"""`python -m missions.cli`: the command line from a checkout without the console script."""

from missions.cli import app

app()
