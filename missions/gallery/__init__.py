"""The gallery: the HTTP endpoint the upload skill's outbox sends photos to, and a page to see them.

- ``store``: photos on disk by content hash, their metadata in SQLite (deduplicated)
- ``images``: is it really a JPEG or PNG (decoded with OpenCV), and its thumbnail
- ``page``: the HTML gallery page
- ``app``: the FastAPI application (upload, list, photo, page) and its upload guard
- ``server``: serve it with uvicorn, in the foreground (`botstage gallery`) or in-process
- ``service``: a run's uploads, with a gallery started for the run when none is configured

It is not a skill: skills never import it; the CLI and the runner do.
"""
