"""What to do: missions in YAML, and the commands that run, check and test them."""

from pathlib import Path

MISSIONS_DIR = Path(__file__).resolve().parent
DEFAULT_MISSION = MISSIONS_DIR / "peoplebot_entertainer.yaml"
