"""Real robots over serial: each protocol's framing, its driver, and the controller chain behind
the interfaces of ``robots/interfaces.py``. The firmware side of each protocol, for tests without
hardware, is in ``robots/emulators``."""
