"""The seven continual-learning methods of the paper, as strategies on one training loop.

>>> from clfd_bench.methods import get_method_class, list_methods
>>> list_methods()
['sg', 'ft', 'rep', 'si', 'mas', 'hn', 'chn']

See :class:`clfd_bench.methods.base.Method` for the interface.
"""

from __future__ import annotations

from clfd_bench.methods.base import Method, StepContext, TaskData
from clfd_bench.methods.ft import FineTuning
from clfd_bench.methods.hn import ChunkedHypernetworkMethod, HypernetworkMethod
from clfd_bench.methods.mas import MemoryAwareSynapses
from clfd_bench.methods.rep import Replay
from clfd_bench.methods.sg import SingleNodePerTask
from clfd_bench.methods.si import SynapticIntelligence

__all__ = [
    "METHODS",
    "Method",
    "StepContext",
    "TaskData",
    "UnknownMethodError",
    "get_method_class",
    "list_methods",
]

METHODS: dict[str, type[Method]] = {
    cls.name: cls
    for cls in (
        SingleNodePerTask,
        FineTuning,
        Replay,
        SynapticIntelligence,
        MemoryAwareSynapses,
        HypernetworkMethod,
        ChunkedHypernetworkMethod,
    )
}
"""Registered methods by name, in the paper's order."""


class UnknownMethodError(KeyError):
    """A method name that is not registered."""

    def __str__(self) -> str:  # KeyError would print the message with quotes
        return str(self.args[0])


def list_methods() -> list[str]:
    """Registered method names."""
    return list(METHODS)


def get_method_class(name: str) -> type[Method]:
    """The method class registered as ``name``.

    Raises:
        UnknownMethodError: the name is not registered; the message lists the valid names.
    """
    try:
        return METHODS[name]
    except KeyError:
        raise UnknownMethodError(
            f"unknown CL method {name!r}; valid methods: {', '.join(METHODS)}"
        ) from None
