"""Perception algorithms the skills use: people tracking, crowd grouping, people from a camera."""
