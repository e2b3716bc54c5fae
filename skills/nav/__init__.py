"""Navigation algorithms the navigation skills use: costmaps, planning, following paths."""
