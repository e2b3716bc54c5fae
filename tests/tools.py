"""Test helpers: system tools some tests need (skipped with a reason outside CI, required under
CI=true), and plug-in wheels installed for real."""

from __future__ import annotations

import base64
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest


def require(tool: str, package: str) -> str:
    path = shutil.which(tool)
    if path is None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"{tool} is not installed; CI must install the Debian package {package}")
        pytest.skip(f"{tool} is not installed (Debian package {package}; CI installs it)")
    return path


def install_wheel(directory: Path, name: str, files: dict[str, str], entry_points: str) -> Path:
    """Build a wheel of distribution ``name`` (version 0.1.0) holding ``files`` and declaring
    ``entry_points`` (entry_points.txt text), install it with pip into ``directory/site``, and
    return that folder (put it on sys.path, or PYTHONPATH for another process)."""
    dist = f"{name.replace('-', '_')}-0.1.0"
    files = {
        **files,
        f"{dist}.dist-info/METADATA": f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1.0\n",
        f"{dist}.dist-info/WHEEL": "Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
        f"{dist}.dist-info/entry_points.txt": entry_points,
    }
    record = []
    for path, text in files.items():
        digest = base64.urlsafe_b64encode(hashlib.sha256(text.encode()).digest()).rstrip(b"=").decode()
        record.append(f"{path},sha256={digest},{len(text.encode())}")
    record.append(f"{dist}.dist-info/RECORD,,")
    files[f"{dist}.dist-info/RECORD"] = "\n".join(record) + "\n"
    wheel = directory / f"{dist}-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as zf:
        for path, text in files.items():
            zf.writestr(path, text)
    target = directory / "site"
    pip = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index", "--target", str(target)]
    subprocess.run([*pip, str(wheel)], check=True)
    return target
