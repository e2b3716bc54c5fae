"""Runnable examples of botstage's Python API: ``python -m botstage.missions.examples.<name>``."""
