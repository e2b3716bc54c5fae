"""How an outbox is set up: where it lives, where it uploads, how it retries.

These are the upload skill's parameters (``skill_params: {upload: {...}}`` in a mission); the
run opens one outbox per distinct folder and endpoint and shares it between nodes.
"""

from __future__ import annotations

from urllib.parse import urlsplit

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

TOKEN_ENV = "BOTSTAGE_GALLERY_TOKEN"


class OutboxSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    endpoint: str | None = Field(
        None,
        description="the gallery's upload URL (e.g. http://127.0.0.1:8765/photos); "
        "none: the run starts a gallery of its own on a free loopback port",
    )
    outbox: str | None = Field(
        None,
        description="the outbox folder; give a fixed one so a restarted robot resumes what it had queued "
        "(default: outbox/ in the run folder)",
    )
    token_env: str = Field(TOKEN_ENV, description="environment variable holding the gallery's token, if any")
    concurrency: int = Field(2, ge=1, le=8, description="uploads in flight at once")
    backoff_initial: float = Field(1.0, gt=0, description="s before the first retry (doubles per attempt)")
    backoff_max: float = Field(60.0, gt=0, description="s: the longest wait between two attempts")
    request_timeout: float = Field(30.0, gt=0, description="s of wall time for one HTTP request")

    @field_validator("endpoint")
    @classmethod
    def _http_url(cls, value: str | None) -> str | None:
        if value is not None:
            parts = urlsplit(value)
            if parts.scheme not in ("http", "https") or not parts.hostname:
                raise ValueError("must be an http:// or https:// URL")
        return value

    @model_validator(mode="after")
    def _backoff_order(self) -> OutboxSettings:
        if self.backoff_max < self.backoff_initial:
            raise ValueError("backoff_max must not be below backoff_initial")
        return self
