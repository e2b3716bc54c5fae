"""System tools some tests need: skipped with a reason outside CI, required under CI=true."""

from __future__ import annotations

import os
import shutil

import pytest


def require(tool: str, package: str) -> str:
    path = shutil.which(tool)
    if path is None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"{tool} is not installed; CI must install the Debian package {package}")
        pytest.skip(f"{tool} is not installed (Debian package {package}; CI installs it)")
    return path
