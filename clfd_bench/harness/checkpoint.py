"""Checkpoints: tensors plus a JSON header, safe to load (``torch.load(weights_only=True)``).

A checkpoint is the bytes of ``torch.save({"format", "header": <JSON text>, "tensors":
{name: tensor}})``. Decoding never unpickles code, so a shared checkpoint cannot run
anything. The header carries the plain data (config, progress, per-task normalisers). The
run directory (:class:`clfd_bench.runs.RunDir`) stores and reads the bytes.

A task snapshot (:func:`encode_snapshot`) is the state of a task being learned (weights,
optimiser, schedule, RNGs at an iteration): nested dicts and lists of tensors and plain
values, loaded the same safe way.
"""

from __future__ import annotations

import io
import json
import pickle
from collections.abc import Mapping
from typing import Any

import torch
from torch import Tensor

__all__ = [
    "CHECKPOINT_FORMAT",
    "SNAPSHOT_FORMAT",
    "CheckpointError",
    "decode_checkpoint",
    "decode_snapshot",
    "encode_checkpoint",
    "encode_snapshot",
]

CHECKPOINT_FORMAT = "clfd-bench-checkpoint/1"
SNAPSHOT_FORMAT = "clfd-bench-task-snapshot/1"


class CheckpointError(ValueError):
    """A checkpoint file cannot be read (truncated, corrupt, not ours); the message names the
    file and the fix. A user-facing error: ``clfd-bench`` prints it as one line, exit 2."""


def _load(data: bytes) -> tuple[Any, str | None]:
    """``(object, None)`` of bytes ``torch.save`` wrote, loaded without unpickling code, or
    ``(None, reason)``: the first sentence of torch's message ("... failed finding central
    directory") when they cannot be read (truncated, corrupt)."""
    try:
        return torch.load(io.BytesIO(data), map_location="cpu", weights_only=True), None
    except (RuntimeError, EOFError, pickle.UnpicklingError, ValueError) as exc:
        return None, (str(exc).splitlines()[0].split(". ")[0] if str(exc)
                      else type(exc).__name__)


def encode_checkpoint(header: Mapping[str, Any], tensors: Mapping[str, Tensor]) -> bytes:
    """The bytes of a checkpoint of ``header`` (JSON-serialisable) and ``tensors``."""
    payload = {
        "format": CHECKPOINT_FORMAT,
        "header": json.dumps(dict(header), allow_nan=False),
        "tensors": {k: v.detach().cpu().contiguous() for k, v in tensors.items()},
    }
    buf = io.BytesIO()
    torch.save(payload, buf)
    return buf.getvalue()


def decode_checkpoint(data: bytes, source: str = "checkpoint"
                      ) -> tuple[dict[str, Any], dict[str, Tensor]]:
    """``(header, tensors)`` of bytes written by :func:`encode_checkpoint`.

    Raises:
        CheckpointError: the bytes are not a clfd-bench checkpoint (``source`` names them).
    """
    obj, reason = _load(data)
    if reason is not None:
        raise CheckpointError(f"{source} is not a readable clfd-bench checkpoint (truncated or "
                              f"corrupt: {reason}); delete it to train the run again from its "
                              "first task")
    if not isinstance(obj, dict) or obj.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{source} is not a clfd-bench checkpoint (format "
                              f"{CHECKPOINT_FORMAT}); delete it to train the run again from "
                              "its first task")
    return json.loads(obj["header"]), dict(obj["tensors"])


def encode_snapshot(body: Mapping[str, Any]) -> bytes:
    """The bytes of a task snapshot: ``body`` holds dicts, lists, tensors and plain values."""
    buf = io.BytesIO()
    torch.save({"format": SNAPSHOT_FORMAT, "body": dict(body)}, buf)
    return buf.getvalue()


def decode_snapshot(data: bytes, source: str = "task snapshot") -> dict[str, Any]:
    """The body of bytes written by :func:`encode_snapshot`.

    Raises:
        CheckpointError: the bytes are not a clfd-bench task snapshot (``source`` names them).
    """
    obj, reason = _load(data)
    if not isinstance(obj, dict) or obj.get("format") != SNAPSHOT_FORMAT:
        why = reason or f"not format {SNAPSHOT_FORMAT}"
        raise CheckpointError(f"{source} is not a readable clfd-bench task snapshot ({why}); "
                              "delete it to learn its task again from the task's start")
    return obj["body"]
