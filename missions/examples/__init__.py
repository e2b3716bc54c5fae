"""Runnable examples of botstage's Python API: ``python -m missions.examples.<name>``."""
