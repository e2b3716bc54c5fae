"""Crowds as the PeopleBot paper defines them: more than one person, each within 1.5 m of another.

Grouping is **single linkage** (scipy's hierarchical clustering cut at 1.5 m): the
paper's words, "each within 1.5 m of another", ask that every member have *some* neighbour that
close, not that all pairs be. A queue of five people 1 m apart is one crowd, as a guide would
see it. The centre of mass is R = (r1 + ... + rn) / n over the members' filtered positions.

A crowd keeps its id from frame to frame while it shares members with the crowd of the frame
before (the one it shares most with), so "the crowd" the robot approaches stays the same one as
people join or leave it.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

CROWD_DISTANCE = 1.5  # m, the paper's


@dataclass(frozen=True)
class Crowd:
    id: int
    members: tuple[int, ...]  # track ids, ascending
    centre: tuple[float, float]  # centre of mass, same frame as the positions

    @property
    def size(self) -> int:
        return len(self.members)


def group(ids: list[int], positions: np.ndarray, distance: float = CROWD_DISTANCE) -> list[list[int]]:
    """Single-linkage groups of more than one person, as lists of indices into ``ids``."""
    if len(ids) < 2:
        return []
    from scipy.cluster.hierarchy import fcluster, linkage  # on first use: scipy's import costs every command

    clusters = fcluster(linkage(positions, method="single"), t=distance, criterion="distance")
    groups = [list(np.flatnonzero(clusters == label)) for label in np.unique(clusters)]
    return [g for g in groups if len(g) > 1]


class CrowdTracker:
    """Crowds from tracked people, frame after frame, with ids that stay (see the module)."""

    def __init__(self, distance: float = CROWD_DISTANCE, min_size: int = 2, ids: Iterator[int] | None = None) -> None:
        self.distance = distance
        self.min_size = max(2, min_size)
        self.crowds: list[Crowd] = []
        self._ids = ids if ids is not None else itertools.count(1)

    def update(self, people: list[tuple[int, float, float]]) -> list[Crowd]:
        """``people``: (track id, x, y); returns this frame's crowds, largest first."""
        ids = [p[0] for p in people]
        positions = np.array([[p[1], p[2]] for p in people], dtype=float).reshape(-1, 2)
        found: list[Crowd] = []
        taken: set[int] = set()
        for indices in group(ids, positions, self.distance):
            if len(indices) < self.min_size:
                continue
            members = tuple(sorted(ids[i] for i in indices))
            centre = positions[indices].mean(axis=0)
            previous = max(
                (c for c in self.crowds if c.id not in taken and set(c.members) & set(members)),
                key=lambda c: len(set(c.members) & set(members)),
                default=None,
            )
            crowd_id = previous.id if previous is not None else next(self._ids)
            taken.add(crowd_id)
            found.append(Crowd(crowd_id, members, (float(centre[0]), float(centre[1]))))
        self.crowds = sorted(found, key=lambda c: (-c.size, c.id))
        return self.crowds
