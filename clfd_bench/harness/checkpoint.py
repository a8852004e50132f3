"""Checkpoints: tensors plus a JSON header, safe to load (``torch.load(weights_only=True)``).

A checkpoint is the bytes of ``torch.save({"format", "header": <JSON text>, "tensors":
{name: tensor}})``. Decoding never unpickles code, so a shared checkpoint cannot run
anything. The header carries the plain data (config, progress, per-task normalisers). The
run directory (:class:`clfd_bench.runs.RunDir`) stores and reads the bytes.
"""

from __future__ import annotations

import io
import json
import pickle
from collections.abc import Mapping
from typing import Any

import torch
from torch import Tensor

__all__ = ["CHECKPOINT_FORMAT", "CheckpointError", "decode_checkpoint", "encode_checkpoint"]

CHECKPOINT_FORMAT = "clfd-bench-checkpoint/1"


class CheckpointError(ValueError):
    """A checkpoint file cannot be read (truncated, corrupt, not ours); the message names the
    file and the fix. A user-facing error: ``clfd-bench`` prints it as one line, exit 2."""


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
    try:
        obj = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except (RuntimeError, EOFError, pickle.UnpicklingError, ValueError) as exc:
        # the first sentence of torch's message ("... failed finding central directory")
        reason = str(exc).splitlines()[0].split(". ")[0] if str(exc) else type(exc).__name__
        raise CheckpointError(f"{source} is not a readable clfd-bench checkpoint (truncated or "
                              f"corrupt: {reason}); delete it to train the run again from its "
                              "first task") from None
    if not isinstance(obj, dict) or obj.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{source} is not a clfd-bench checkpoint (format "
                              f"{CHECKPOINT_FORMAT}); delete it to train the run again from "
                              "its first task")
    return json.loads(obj["header"]), dict(obj["tensors"])
