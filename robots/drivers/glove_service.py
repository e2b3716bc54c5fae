"""The run service of the book's IMU glove (robots/drivers/gesture_glove.py), the hardware set's:
registered under ``botstage.services`` like any plug-in's."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from botstage.robots.drivers.gesture_glove import glove_for


class GestureService:
    """gesture: the book's IMU glove, opened only when a skill reads it."""

    name = "gesture"

    def __init__(self) -> None:
        self.glove: Any = None

    def open(self, session: Any) -> Mapping[str, Any]:
        self.glove = glove_for(session.clock)
        return {"gesture": self.glove}

    def close(self) -> None:
        close = getattr(self.glove, "close", None)
        if close is not None:
            close()
