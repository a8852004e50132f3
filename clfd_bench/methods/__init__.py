"""Continual-learning methods as strategies on one training loop: the paper's seven, three
more written through the same interface (online EWC, A-GEM, PackNet) and any plugin
(:mod:`clfd_bench.methods.registry`; docs/methods.md).

>>> from clfd_bench.methods import get_method_class, list_methods
>>> list_methods()[:10]
['sg', 'ft', 'rep', 'si', 'mas', 'hn', 'chn', 'ewc', 'agem', 'packnet']

See :class:`clfd_bench.methods.base.Method` for the interface.
"""

from __future__ import annotations

from clfd_bench.learning.part_config import Rule
from clfd_bench.methods.base import Method, StepContext, TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod
from clfd_bench.methods.registry import (
    BUILTIN,
    ENTRY_POINT_GROUP,
    MethodClassError,
    UnknownMethodError,
    check_method_class,
    get_method_class,
    installed_plugins,
    list_methods,
    normalise_method,
    own_config_file,
)

__all__ = [
    "BUILTIN",
    "ConditionedNodeMethod",
    "ENTRY_POINT_GROUP",
    "METHODS",
    "Method",
    "MethodClassError",
    "Rule",
    "StepContext",
    "TaskData",
    "UnknownMethodError",
    "check_method_class",
    "get_method_class",
    "installed_plugins",
    "list_methods",
    "normalise_method",
    "own_config_file",
]

METHODS = BUILTIN
"""The built-in methods by name (alias of :data:`~clfd_bench.methods.registry.BUILTIN`)."""
