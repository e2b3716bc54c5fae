"""The built-in simulator: a world stepped by the SimClock, and its devices behind the interfaces."""
