"""Checkpoints: tensors plus a JSON header, safe to load (``torch.load(weights_only=True)``).

A checkpoint file is ``torch.save({"header": <JSON text>, "tensors": {name: tensor}})``,
written atomically. Loading never unpickles code, so a shared checkpoint cannot run
anything. The header carries the plain data (config, progress, per-task normalisers).
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Mapping
from typing import Any

import torch
from torch import Tensor

from clfd_bench.io import atomic_write_bytes

__all__ = ["CHECKPOINT_FORMAT", "load_checkpoint", "save_checkpoint"]

CHECKPOINT_FORMAT = "clfd-bench-checkpoint/1"


def save_checkpoint(
    path: str | os.PathLike[str], header: Mapping[str, Any], tensors: Mapping[str, Tensor]
) -> None:
    """Write ``header`` (JSON-serialisable) and ``tensors`` to ``path`` atomically."""
    payload = {
        "format": CHECKPOINT_FORMAT,
        "header": json.dumps(dict(header), allow_nan=False),
        "tensors": {k: v.detach().cpu().contiguous() for k, v in tensors.items()},
    }
    buf = io.BytesIO()
    torch.save(payload, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: str | os.PathLike[str]) -> tuple[dict[str, Any], dict[str, Tensor]]:
    """Read a checkpoint written by :func:`save_checkpoint` -> ``(header, tensors)``.

    Raises:
        ValueError: the file is not a clfd-bench checkpoint.
    """
    obj = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(obj, dict) or obj.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{path} is not a clfd-bench checkpoint (format {CHECKPOINT_FORMAT})")
    return json.loads(obj["header"]), dict(obj["tensors"])
