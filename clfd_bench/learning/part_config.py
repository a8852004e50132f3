"""Hyperparameters of one learned model (:class:`PartConfig`), the type and valid range of
every one of them (:data:`PART_RULES`, checked by :class:`PartConfig` and by
:func:`clfd_bench.harness.config.resolve_config`, which also names where a bad value came
from), and the error every config check raises. Lives below the methods and the harness,
which both read it."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any

from clfd_bench.learning.batches import BATCH_KINDS
from clfd_bench.learning.hnet_reg import REG_MODES
from clfd_bench.learning.mlp import ACTIVATIONS
from clfd_bench.learning.odeint import ADAPTIVE_SOLVERS, BACKENDS, FIXED_SOLVERS

__all__ = [
    "COMMON_KEYS",
    "ConfigError",
    "Constraint",
    "IMPORTANCE_MERGES",
    "OMITTED_AT_DEFAULT",
    "PART_CONSTRAINTS",
    "PART_FIELDS",
    "PART_RULES",
    "PartConfig",
    "REFINE_MAX_SUBSTEPS",
    "SNODE_KEYS",
    "Rule",
    "TIME_AXES",
]


class ConfigError(ValueError):
    """A baselines file or an override is invalid; the message says what and how to fix it."""


_TYPE_NAMES = {
    "int": "an integer",
    "float": "a number",
    "bool": "true or false",
    "str": "a string",
    "ints": "a list of integers",
}


@dataclass(frozen=True)
class Rule:
    """The type and valid range of one configuration value.

    Attributes:
        kind: ``int``, ``float`` (always finite; an integer is accepted), ``bool``, ``str``
            or ``ints`` (a non-empty list of integers, each in the range).
        lo, hi: bounds (None: unbounded); ``lo_open`` / ``hi_open`` exclude them.
        choices: the valid strings (``str``).
        optional: None (unset) is valid too.
        what: what the value means, for error messages.
    """

    kind: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[str, ...] = ()
    optional: bool = False
    what: str = ""

    def describe(self) -> str:
        """The valid values in words, e.g. ``a finite number > 0``."""
        if self.kind == "bool":
            return "true or false"
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.kind == "float":
            lo, hi = self.lo, self.hi
            if lo is not None and hi is not None:
                return (f"a number in {'(' if self.lo_open else '['}{lo:g}, {hi:g}"
                        f"{')' if self.hi_open else ']'}")
            base = "a finite number"
        else:
            base = "an integer" if self.kind == "int" else "a non-empty list of integers"
            lo, hi = self.lo, self.hi
            if lo is not None and hi is not None:
                return f"{base} in {int(lo)}..{int(hi)}"
        bounds = []
        if lo is not None:
            bounds.append(f"{'>' if self.lo_open else '>='} {lo:g}")
        if hi is not None:
            bounds.append(f"{'<' if self.hi_open else '<='} {hi:g}")
        return f"{base} {' and '.join(bounds)}".rstrip()

    def coerce(self, value: Any) -> tuple[Any, str | None]:
        """``(value in its Python type, None)``, or ``(value, "<type in words>")`` when the
        value has the wrong type (a bool is never a number)."""
        if value is None and self.optional:
            return None, None
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if self.kind == "ints":
            ok = isinstance(value, list | tuple) and all(
                isinstance(v, int) and not isinstance(v, bool) for v in value)
            return (tuple(value), None) if ok else (value, _TYPE_NAMES["ints"])
        if self.kind == "bool":
            return (value, None) if isinstance(value, bool) else (value, _TYPE_NAMES["bool"])
        if self.kind == "int":
            ok = number and isinstance(value, int)
            return (value, None) if ok else (value, _TYPE_NAMES["int"])
        if self.kind == "float":
            return (float(value), None) if number else (value, _TYPE_NAMES["float"])
        if self.kind == "str":
            return (value, None) if isinstance(value, str) else (value, _TYPE_NAMES["str"])
        raise AssertionError(f"unknown rule kind {self.kind!r}")  # pragma: no cover

    def _in_range(self, x: float) -> bool:
        if self.kind == "float" and not math.isfinite(x):
            return False
        if self.lo is not None and (x <= self.lo if self.lo_open else x < self.lo):
            return False
        return self.hi is None or (x < self.hi if self.hi_open else x <= self.hi)

    def valid(self, value: Any) -> bool:
        """Whether a value of the right type (after :meth:`coerce`) is in range."""
        if value is None:
            return self.optional
        if self.kind == "ints":
            return len(value) > 0 and all(self._in_range(v) for v in value)
        if self.kind == "bool":
            return True
        if self.kind == "str":
            return not self.choices or value in self.choices
        return self._in_range(value)

    def check(self, name: str, value: Any) -> tuple[Any, str | None]:
        """``(coerced value, None)``, or ``(value, "name must be ..., got ...")``."""
        coerced, wrong_type = self.coerce(value)
        if wrong_type is not None:
            return value, f"{name} must be {wrong_type}, got {value!r}"
        if not self.valid(coerced):
            what = f" ({self.what})" if self.what else ""
            return value, f"{name} must be {self.describe()}{what}, got {value!r}"
        return coerced, None


_SOLVERS = ADAPTIVE_SOLVERS + FIXED_SOLVERS
TIME_AXES = ("uniform", "first_demo")
IMPORTANCE_MERGES = ("per_task", "cumulative")
"""The NODE's time axis: ``uniform`` = the task's ``times`` (LASA: ``arange(T) * dt`` with the
file's mean ``dt``), ``first_demo`` = the first demo's own time stamps (the released code's)."""
_SIZE = 65536  # sanity bound of widths and embedding sizes (the paper's largest: 8192)

PART_RULES: dict[str, Rule] = {
    # training
    "iterations": Rule("int", lo=1, what="optimiser steps per task"),
    "lr": Rule("float", lo=0, lo_open=True, what="Adam learning rate"),
    "lr_schedule": Rule("str", choices=("constant", "cosine")),
    "lr_min_factor": Rule("float", lo=0, hi=1, what="final lr / lr of the cosine schedule"),
    "lr_warmup": Rule("float", lo=0, hi=1, what="fraction of a task's iterations over which "
                      "the lr rises linearly to its value; 0: none"),
    "stop_window": Rule("int", lo=0, what="iterations per window of the stop rule's smoothed "
                        "loss; 0: off, every task runs all its iterations"),
    "stop_rel": Rule("float", lo=0, hi=1, hi_open=True, what="relative improvement of the "
                     "smoothed loss below which a window is a plateau"),
    "stop_decays": Rule("int", lo=0, what="plateaus that divide the lr by 10 before one "
                        "stops the task"),
    "refine_gap": Rule("float", lo=0, what="solver gap (positions: data units; orientations: "
                       "degrees) above which a stopped task trains on with twice the solver "
                       "steps; 0: off"),
    # networks
    "node_hidden": Rule("ints", lo=1, hi=_SIZE, what="hidden widths of the NODE"),
    "activation": Rule("str", choices=tuple(ACTIVATIONS)),
    "task_emb_dim": Rule("int", lo=1, hi=_SIZE, what="task embedding size"),
    "hnet_hidden": Rule("ints", lo=1, hi=_SIZE, what="hidden widths of the hypernetwork"),
    "hnet_activation": Rule("str", choices=tuple(ACTIVATIONS)),
    "chunk_emb_dim": Rule("int", lo=1, hi=_SIZE, what="chunk embedding size"),
    "chunk_dim": Rule("int", lo=1, hi=2**24, what="weights generated per chunk"),
    # regularisers
    "beta": Rule("float", lo=0, what="weight of the hypernetwork regulariser"),
    "hnet_reg": Rule("str", choices=REG_MODES),
    "hnet_reg_samples": Rule("int", lo=1, what="earlier tasks per step for hnet_reg=sampled"),
    "si_c": Rule("float", lo=0, what="weight of the SI penalty"),
    "si_xi": Rule("float", lo=0, lo_open=True, what="SI damping; 0 divides by zero"),
    "mas_lambda": Rule("float", lo=0, what="weight of the MAS penalty"),
    "mas_points": Rule("int", lo=0, what="samples for the MAS importance, 0: all"),
    "importance_merge": Rule("str", choices=IMPORTANCE_MERGES),
    # batches
    "batch": Rule("str", choices=BATCH_KINDS),
    "tsub": Rule("int", lo=2, what="window length in samples"),
    "points": Rule("int", lo=2, what="samples per subsampled trajectory"),
    "horizon_start": Rule("float", lo=0, lo_open=True, hi=1, what="share of the trajectory"),
    "horizon_ramp": Rule("float", lo=0, hi=1, what="share of the iterations"),
    "segments": Rule("bool"),
    # ODE solver
    "solver": Rule("str", choices=_SOLVERS),
    "rtol": Rule("float", lo=0, lo_open=True, what="relative tolerance"),
    "atol": Rule("float", lo=0, lo_open=True, what="absolute tolerance"),
    "substeps": Rule("int", lo=1, what="solver steps per output interval"),
    "solver_backend": Rule("str", choices=BACKENDS),
    "eval_solver": Rule("str", choices=_SOLVERS, optional=True),
    "eval_rtol": Rule("float", lo=0, lo_open=True, optional=True, what="relative tolerance"),
    "eval_atol": Rule("float", lo=0, lo_open=True, optional=True, what="absolute tolerance"),
    "eval_substeps": Rule("int", lo=1, optional=True, what="steps per output interval"),
    # data
    "normalize": Rule("bool"),
    "tangent_goal": Rule("str", choices=("demo", "task")),
    "tangent_scale": Rule("float", lo=0, lo_open=True,
                          what="factor on the orientation tangent vectors the NODE learns"),
    "time_axis": Rule("str", choices=TIME_AXES),
    # stable NODE (--node s), clfd_bench.learning.stable
    "lyap_hidden": Rule("ints", lo=1, hi=_SIZE, what="hidden widths of the sNODE's ICNN"),
    "snode_alpha": Rule("float", lo=0, lo_open=True, what="decay rate of V along the sNODE"),
    "snode_eps": Rule("float", lo=0, lo_open=True, what="weight of V's quadratic floor"),
    "snode_rehu": Rule("float", lo=0, lo_open=True, what="ReHU width of the sNODE's ICNN"),
    "snode_clock": Rule("bool"),
    "snode_tangent": Rule("bool"),
}
"""The type and valid range of every :class:`PartConfig` field (one entry per field)."""


@dataclass(frozen=True)
class Constraint:
    """A rule between several values of one :class:`PartConfig` (checked after the ranges).

    Attributes:
        keys: the values involved (named in the error).
        holds: ``holds(values) -> bool`` on the config's values by name.
        text: what must hold and how to fix it.
    """

    keys: tuple[str, ...]
    holds: Callable[[Mapping[str, Any]], bool]
    text: str


def _segments_ok(c: Mapping[str, Any]) -> bool:
    uses_segments = c["batch"] == "trajectories" and c["segments"] and c["horizon_start"] < 1
    return not uses_segments or (c["solver"] == "rk4" and c["solver_backend"] == "fused")


REFINE_MAX_SUBSTEPS = 8
"""The most solver steps per interval ``refine_gap`` refines a task to (three doublings of
``substeps = 1``; each doubles the cost of an iteration)."""


def _refine_ok(c: Mapping[str, Any]) -> bool:
    return c["refine_gap"] == 0 or (c["stop_window"] > 0 and c["batch"] == "trajectories"
                                    and c["solver"] in FIXED_SOLVERS)


PART_CONSTRAINTS: tuple[Constraint, ...] = (
    Constraint(
        ("segments", "batch", "horizon_start", "solver", "solver_backend"), _segments_ok,
        "segments (batch = trajectories, segments = true, horizon_start < 1) need solver = "
        "rk4 with solver_backend = fused; set segments=false, or solver=rk4 and "
        "solver_backend=fused",
    ),
    Constraint(
        ("refine_gap", "stop_window", "batch", "solver"), _refine_ok,
        "refine_gap > 0 refines a task's fixed solver steps once its stop rule ends it, so it "
        "needs stop_window > 0, batch = trajectories and a fixed-step solver (rk4, midpoint, "
        "euler); set refine_gap=0, or those",
    ),
)
"""Rules between values, checked by :class:`PartConfig` and ``resolve_config``."""


@dataclass(frozen=True)
class PartConfig:
    """Hyperparameters of one learned model (the positions, or the orientations of RoboTasks).

    Training:
        iterations: optimiser steps per task. lr: Adam learning rate (all parameters).
        lr_schedule: ``constant`` or ``cosine`` (decays to ``lr * lr_min_factor``).
        lr_warmup: fraction of each task's iterations over which the learning rate rises
        linearly from ``lr / n`` to the schedule's value (``n`` = the warm-up's iterations);
        0 (the default, and the paper's): none. Left out of saved configs at 0.
        stop_window, stop_rel, stop_decays: the stop rule on the training loss
        (:mod:`clfd_bench.learning.stop_rule`): the mean loss over windows of
        ``stop_window`` iterations, from the end of the warm-up and the horizon's growth; a
        window not ``stop_rel`` (relative) below the best earlier one is a plateau; the first
        ``stop_decays`` plateaus divide the lr by 10, the next stops the task, so
        ``iterations`` becomes a cap. ``stop_window = 0`` (the default; paper, fast,
        smoke): off. Left out of saved configs at their defaults.
        refine_gap: the solver gap (:meth:`~clfd_bench.harness.learner.PartLearner.solver_gap`;
        positions in data units, orientations in degrees) a task may end with. When the stop
        rule ends a task whose gap is larger, the task trains on from its weights with
        twice the solver steps per interval (``substeps``), at the learning rate it ended
        with, under a fresh stop rule (which may lower it further), until the
        gap is at most ``refine_gap``, the steps reach :data:`REFINE_MAX_SUBSTEPS` or the
        task's ``iterations`` are spent (:mod:`clfd_bench.harness.loop`). 0 (the default):
        off, and left out of saved configs.
    Batches (:mod:`clfd_bench.learning.batches`):
        batch: ``windows`` (paper: ``tsub`` consecutive samples) or ``trajectories`` (whole
        trajectories subsampled to ``points``, horizon growing from ``horizon_start`` over the
        first ``horizon_ramp`` of the iterations; ``segments``: short horizons cover the whole
        trajectory as parallel segments).
    ODE solver (:mod:`clfd_bench.learning.odeint`): ``solver``, ``rtol``, ``atol``,
        ``substeps`` for training; ``eval_*`` for predictions (default: the training ones);
        ``solver_backend``: ``fused`` (hand-written reverse sweep, same values) or
        ``autograd`` (torchdiffeq / autograd, as the original code).
    NODE: ``node_hidden`` widths, ``activation``; ``task_emb_dim`` for task-conditioned
        NODEs and hypernetworks.
    Hypernetworks: ``hnet_hidden``, ``hnet_activation``, ``beta``; ``hnet_reg`` = ``all``
        (the paper's loop over past tasks), ``batched`` (same maths, one pass) or
        ``sampled`` (``hnet_reg_samples`` past tasks per step); CHN: ``chunk_emb_dim``,
        ``chunk_dim``.
    SI: ``si_c``, ``si_xi``. MAS: ``mas_lambda``; ``mas_points`` data points for the
        importance (0: all samples of the task). Both: ``importance_merge``
        (:data:`IMPORTANCE_MERGES`): ``per_task``, each task's importance estimated from that
        task alone (the paper's equations), or ``cumulative``, the released code's: the
        running estimate is never reset, so every task's importance also counts all earlier
        tasks' again (SI: the path integral; MAS: the current-task importance) and the
        penalty grows about quadratically with the number of tasks.
    Data: ``normalize`` (per-task mean/std); ``tangent_goal`` (orientation: ``demo`` = Log
        relative to each demo's final quaternion as in the paper, ``task`` = the task goal);
        ``tangent_scale`` (orientation only: the NODE learns tangent vectors times this
        factor, predictions are divided by it before the Exp map; the released RoboTasks
        orientation commands use 100; with ``normalize`` on, the factor cancels);
        ``time_axis`` (:data:`TIME_AXES`: ``uniform``, or ``first_demo``, the first demo's own
        time stamps as the released code; differs only on LASA, where each demo has its own).
    Stable NODE (read only by ``--node s`` runs, :mod:`clfd_bench.learning.stable`; saved
        only when not at their defaults, :data:`SNODE_KEYS`): ``lyap_hidden`` widths of the
        Lyapunov function's ICNN, ``snode_alpha`` its decay rate, ``snode_eps`` its quadratic
        floor, ``snode_rehu`` the ICNN's ReHU width, ``snode_clock`` the follow-up's time input
        (voids the stability guarantee), ``snode_tangent`` V measured from the ICNN's tangent
        plane at the goal instead of its value there (not the follow-up's; removes the region
        where ``V`` is its quadratic floor alone). The nominal field uses ``node_hidden`` and
        ``activation``.
    """

    iterations: int
    lr: float
    node_hidden: tuple[int, ...]
    lr_schedule: str = "constant"
    lr_min_factor: float = 0.0
    lr_warmup: float = 0.0
    stop_window: int = 0
    stop_rel: float = 0.01
    stop_decays: int = 0
    refine_gap: float = 0.0
    activation: str = "elu"
    task_emb_dim: int = 0
    hnet_hidden: tuple[int, ...] = ()
    hnet_activation: str = "relu"
    chunk_emb_dim: int = 0
    chunk_dim: int = 0
    beta: float = 0.0
    hnet_reg: str = "all"
    hnet_reg_samples: int = 1
    si_c: float = 0.0
    si_xi: float = 0.0
    mas_lambda: float = 0.0
    mas_points: int = 0
    importance_merge: str = "per_task"
    batch: str = "windows"
    tsub: int = 20
    points: int = 50
    horizon_start: float = 1.0
    horizon_ramp: float = 0.0
    segments: bool = False
    solver: str = "dopri5"
    rtol: float = 1e-6
    atol: float = 1e-7
    substeps: int = 1
    solver_backend: str = "fused"
    eval_solver: str | None = None
    eval_rtol: float | None = None
    eval_atol: float | None = None
    eval_substeps: int | None = None
    normalize: bool = True
    tangent_goal: str = "demo"
    tangent_scale: float = 1.0
    time_axis: str = "uniform"
    lyap_hidden: tuple[int, ...] = (100, 100)
    snode_alpha: float = 0.5
    snode_eps: float = 1e-4
    snode_rehu: float = 0.01
    snode_clock: bool = False
    snode_tangent: bool = False
    extras: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        if isinstance(self.extras, Mapping):  # a dict is accepted and stored sorted
            object.__setattr__(self, "extras", tuple(sorted(self.extras.items())))
        for f in fields(self):
            if f.name == "extras":
                continue  # checked by the method's own rules (resolve_config)
            value = getattr(self, f.name)
            if f.name not in COMMON_KEYS and value == f.default:
                continue  # a method-specific key left at its default: not used by the method
            _, problem = PART_RULES[f.name].check(f.name, value)
            if problem:
                raise ConfigError(problem)
        values = dataclasses.asdict(self)
        for rule in PART_CONSTRAINTS:
            if not rule.holds(values):
                shown = ", ".join(f"{k} = {values[k]!r}" for k in rule.keys)
                raise ConfigError(f"{shown}: {rule.text}")

    def resolved(self) -> PartConfig:
        """A copy with the ``eval_*`` settings filled in from the training ones."""
        return dataclasses.replace(
            self,
            eval_solver=self.eval_solver or self.solver,
            eval_rtol=self.eval_rtol if self.eval_rtol is not None else self.rtol,
            eval_atol=self.eval_atol if self.eval_atol is not None else self.atol,
            eval_substeps=self.eval_substeps if self.eval_substeps is not None else self.substeps,
        )

    def extra(self, name: str) -> Any:
        """The value of a method's own hyperparameter ``name`` (see
        ``Method.own_hyperparameters``).

        Raises:
            KeyError: the config has no such value; the message lists the ones it has.
        """
        for key, value in self.extras:
            if key == name:
                return value
        raise KeyError(f"no own hyperparameter {name!r} in this config (it has: "
                       f"{', '.join(k for k, _ in self.extras) or 'none'}); declare it in "
                       "the method's own_hyperparameters and set it in its TOML")

    def to_dict(self) -> dict[str, Any]:
        """Plain data (lists for tuples) for JSON; ``extras`` as a table, left out when
        empty (so configs of the built-in methods read as before)."""
        out = dataclasses.asdict(self)
        extras = out.pop("extras")
        for key in OMITTED_AT_DEFAULT:  # runs saved before these keys existed read the same
            if out[key] == PART_FIELDS[key].default:
                del out[key]
        out = {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}
        if extras:
            out["extras"] = {k: list(v) if isinstance(v, tuple) else v for k, v in extras}
        return out


PART_FIELDS: dict[str, dataclasses.Field] = {
    f.name: f for f in fields(PartConfig) if f.name != "extras"
}
"""The configuration keys: every :class:`PartConfig` field but ``extras`` (a method's own
hyperparameters, which its own rules check)."""
assert set(PART_RULES) == set(PART_FIELDS), "every PartConfig field needs one PART_RULES entry"

COMMON_KEYS = frozenset(PART_FIELDS) - {
    "task_emb_dim", "hnet_hidden", "hnet_activation", "chunk_emb_dim", "chunk_dim", "beta",
    "hnet_reg", "hnet_reg_samples", "si_c", "si_xi", "mas_lambda", "mas_points",
    "importance_merge",
}
"""Keys every method accepts; the rest are method-specific (see ``Method.hyperparameters``)."""

SNODE_KEYS = ("lyap_hidden", "snode_alpha", "snode_eps", "snode_rehu", "snode_clock",
              "snode_tangent")
"""The stable NODE's keys: left out of :meth:`PartConfig.to_dict` at their defaults, so the
saved configs of NODE^T/NODE^I runs, and of runs made before they existed, do not change."""

OMITTED_AT_DEFAULT = (*SNODE_KEYS, "lr_warmup", "stop_window", "stop_rel", "stop_decays",
                      "refine_gap")
"""Keys :meth:`PartConfig.to_dict` leaves out at their defaults (added after runs had been
saved; a run without them has the defaults)."""
