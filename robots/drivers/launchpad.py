"""The Chefbot's Tiva C Launchpad over a serial port (pyserial, 115200 8N1).

The link (``serial_link.SerialLink``: reconnection, garbage, the safe command on every
connection and exit) with the Launchpad's line protocol (``launchpad_protocol.LineDecoder``);
its listener is the controller chain (``chefbot_base.ChefbotBase``). Motor commands are clamped
to the PWM range whatever asked for them, and zero speed is the safe command.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from botstage.robots.drivers.launchpad_protocol import BAUD, RESET_COMMAND, LineDecoder, speed_command
from botstage.robots.drivers.serial_link import Listener, SerialLink

ZERO = speed_command(0, 0)


class LaunchpadDriver(SerialLink):
    """The serial link to the Launchpad; see the module."""

    def __init__(
        self,
        port: str,
        listener: Listener | None = None,
        *,
        baud: int = BAUD,
        backoff: tuple[float, float] = (0.05, 2.0),
        silence_s: float = 2.0,
        read_timeout: float = 0.02,
        start: bool = True,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__(
            port,
            LineDecoder(),
            ZERO,
            listener,
            name="launchpad",
            baud=baud,
            backoff=backoff,
            silence_s=silence_s,
            read_timeout=read_timeout,
            start=start,
            monotonic=monotonic,
        )

    def send_speeds(self, left: int, right: int) -> bool:
        """Motor outputs (PWM, clamped to ±255); False when the port is down or closing."""
        if not self.motion_allowed and (left or right):
            left = right = 0
        ok = self.send(speed_command(left, right))
        if ok:
            self.counters["speed_commands"] += 1
        return ok

    def reset_board(self) -> bool:
        return self.send(RESET_COMMAND)
