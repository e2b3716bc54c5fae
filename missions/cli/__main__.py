"""`python -m botstage.missions.cli`: the command line from a checkout without the console script."""

from botstage.missions.cli import app

app()
