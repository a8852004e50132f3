"""The hyperparameter profiles of ``baselines/*.toml`` (no heavy imports, so the command line
can list them without loading torch)."""

from __future__ import annotations

__all__ = ["PROFILES", "PROFILE_NAMES", "profile_help"]

PROFILES: dict[str, str] = {
    "paper": "the paper's tables exactly",
    "full": "the paper's networks, trained to a stop rule on the loss",
    "fast": "scaled-down networks, minutes on a CPU",
    "smoke": "seconds, for tests",
}
"""Profile name -> what it is (baselines/README.md has the details)."""

PROFILE_NAMES: tuple[str, ...] = tuple(PROFILES)
"""The profile names, in the order tables list them."""


def profile_help(default: str) -> str:
    """The ``--profile`` option's help text, e.g. ``paper, full, fast or smoke (default
    fast)``."""
    return f"{', '.join(PROFILE_NAMES[:-1])} or {PROFILE_NAMES[-1]} (default {default})"
