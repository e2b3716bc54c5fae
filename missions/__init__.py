"""What to do: missions in YAML, and the commands that run, check and test them."""

from pathlib import Path

MISSIONS_DIR = Path(__file__).resolve().parent
EXAMPLES_DIR = MISSIONS_DIR / "examples"  # the shipped missions
DEFAULT_MISSION = EXAMPLES_DIR / "peoplebot_entertainer.yaml"
