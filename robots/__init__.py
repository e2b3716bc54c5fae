"""What a robot is: clocks, interfaces, profiles, the simulator and hardware drivers.

This layer knows nothing of skills, trees or missions.
"""

from pathlib import Path

PROFILES_DIR = Path(__file__).resolve().parent / "profiles"
