"""cablekit's messages go through the :mod:`logging` module, under the ``cablekit`` logger, so
that a controller or a notebook can silence them or route them
(``logging.getLogger("cablekit").setLevel(logging.WARNING)``). Progress lines that a call asked
for (``progress=True``) are ``INFO``; notes about missing optional extras ``WARNING``.

Until the application configures logging itself (any handler on ``cablekit`` or the root
logger), the first message installs a plain handler on stdout, so a script or the CLI shows what
it showed before."""

from __future__ import annotations

import logging
import sys

__all__ = ["LOG", "info", "warning"]

LOG = logging.getLogger("cablekit")


def _ensure_handler() -> None:
    if not LOG.hasHandlers():
        handler = logging.StreamHandler(sys.stdout)
        handler.setFormatter(logging.Formatter("%(message)s"))
        LOG.addHandler(handler)
        if LOG.level == logging.NOTSET:
            LOG.setLevel(logging.INFO)


def info(message: str) -> None:
    """A progress line (``INFO``)."""
    _ensure_handler()
    LOG.info(message)
    for h in LOG.handlers:
        h.flush()


def warning(message: str) -> None:
    """A note the user should see (``WARNING``)."""
    _ensure_handler()
    LOG.warning(message)
