"""Names of what a deployment's processes serve each other, in one place for the processes that
serve and call them and for the access policy that says who may."""

from __future__ import annotations


def lockstep_service(process: str) -> str:
    """The service through which the mission's process steps ``process`` in lockstep."""
    return f"/{process}/lockstep"
