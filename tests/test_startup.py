"""Every command starts a Python process: what a command never uses is not imported.

scipy's signal, stats, spatial, ndimage, cluster and optimize packages and filterpy (which imports
scipy.stats) cost two to three seconds per process on the CI machine; drawing or checking a
mission needs none of them, so the modules that use them import them where first used.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HEAVY = ("scipy.signal", "scipy.stats", "scipy.spatial", "scipy.ndimage", "scipy.cluster", "scipy.optimize", "filterpy")

PROBE = """
import json, sys
from botstage.missions.check import check
from botstage.skills.registry import Registry
Registry.builtin()
check(sys.argv[1])
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in ("scipy", "filterpy"))))
"""


def test_checking_a_mission_imports_no_heavy_package() -> None:
    mission = str(ROOT / "missions" / "examples" / "peoplebot_entertainer.yaml")
    result = subprocess.run(
        [sys.executable, "-c", PROBE, mission], capture_output=True, text=True, cwd=ROOT, timeout=120, check=True
    )
    loaded = json.loads(result.stdout.strip().splitlines()[-1])
    assert not [m for m in loaded if m.startswith(HEAVY)], loaded


def test_the_heavy_packages_still_load_where_they_are_used() -> None:
    """The lazy imports are real: the functions that need scipy and filterpy work (no stale names)."""
    import numpy as np

    from botstage.robots.gridmap import FREE, GridMap
    from botstage.robots.interfaces import Pose2D
    from botstage.skills.nav.costmap import inflated_costs
    from botstage.skills.nav.ekf import PoseEKF
    from botstage.skills.nav.stack import blocked_cells
    from botstage.skills.perception.crowd import group
    from botstage.skills.perception.tracking import PeopleTracks
    from botstage.skills.speech.denoise import suppress_noise

    data = np.full((40, 40), FREE, dtype=np.int8)
    data[20, 5:35] = 100
    grid = GridMap(data, 0.05)
    assert np.isinf(inflated_costs(grid, 0.2)[20, 20])
    assert blocked_cells(grid).query([20.5, 20.5])[0] < 1e-9
    assert sorted(map(sorted, group([1, 2, 3], np.array([[0.0, 0.0], [1.0, 0.0], [9.0, 9.0]])))) == [[0, 1]]
    assert suppress_noise(np.zeros(4000, dtype=np.int16)).shape == (4000,)
    assert PoseEKF(Pose2D(1.0, 2.0, 0.0)).pose == Pose2D(1.0, 2.0, 0.0)
    tracks = PeopleTracks()
    for step in range(5):  # a Kalman filter per person, matched by the assignment solver
        confirmed = tracks.update(0.1 * step, [(1.0 + 0.1 * step, 0.0, None), (4.0, 1.0, None)])
    assert len(confirmed) == 2
