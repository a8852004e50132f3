"""The grid of training runs a leaderboard needs, and which of them are already done.

A run is identified by :class:`RunSpec`; its directory under the leaderboard's output is
derived from the spec alone, so starting a leaderboard again finds finished runs and skips
them, and a half-finished run resumes from its last finished task (a grid worker,
:mod:`clfd_bench.harness.worker`, resumes it by itself). Whether a run is finished is the
run directory's to say (:meth:`clfd_bench.runs.RunDir.status`): every task trained and,
with simulation, every prediction executed by the current simulator.
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass
from itertools import product
from pathlib import Path
from typing import Any

from clfd_bench.harness.run import TrainSpec
from clfd_bench.harness.worker import Job
from clfd_bench.runs import RunDir, RunStatus

__all__ = ["DEFAULT_OPTIONS", "EXECUTORS", "MAX_LOCKSTEP", "GridOptions", "RunSpec",
           "lockstep_batches", "lockstep_key", "make_grid", "reread_simulator", "run_state",
           "run_status"]

MAX_LOCKSTEP = 8
"""The most runs one process trains in lockstep."""

_SAFE = re.compile(r"[A-Za-z0-9_.+-]+")

EXECUTORS = ("local", "ray")
"""Where a grid's runs can run (:mod:`clfd_bench.leaderboard.executors`)."""


@dataclass(frozen=True)
class GridOptions:
    """The options every grid shares (``clfd-bench leaderboard``, ``paper run``, the
    studies), one value from the command line to the executors: what each run does beyond its
    method, seed and order, and where the runs run.

    Attributes:
        node: the runs' NODE variant (a named entry's own node wins; grids with NODE variants
            of their own, the paper's and the loop study's, do not use it).
        tasks: stop each run after this many tasks (None: all of the dataset's).
        sim: execute each run's predictions in simulation.
        executor: ``"local"`` (processes on this machine) or ``"ray"`` (:data:`EXECUTORS`).
        workers: parallel local worker processes.
        address: Ray cluster address (None: start a local Ray instance).
        lockstep: let the local executor train runs that differ only in seed or order in
            one process, in lockstep (:func:`lockstep_batches`); False: one process per run.

    Raises:
        InputError: ``workers`` below 1 or an unknown ``executor`` (one line naming the
            option), when the value is made: before any run is planned.
    """

    node: str = "t"
    tasks: int | None = None
    sim: bool = True
    executor: str = "local"
    workers: int = 1
    address: str | None = None
    lockstep: bool = True

    def __post_init__(self) -> None:
        from clfd_bench.harness.validate import InputError, check_count

        check_count("--workers", self.workers)
        if self.executor not in EXECUTORS:
            raise InputError(f"--executor {self.executor}: unknown executor; valid: "
                             f"{', '.join(EXECUTORS)}")

    @classmethod
    def from_meta(cls, meta: dict[str, Any], **where: Any) -> GridOptions:
        """The node, tasks and simulation a leaderboard's runs had (its ``leaderboard.json``
        ``meta``), with ``where`` they run now (``executor``, ``workers``, ``address``)."""
        return cls(node=meta.get("node", "t"), tasks=meta.get("tasks"),
                   sim=bool(meta.get("sim", True)), **where)


DEFAULT_OPTIONS = GridOptions()
"""Every grid option at its default: NODE^T, every task, with simulation, one local worker."""


@dataclass(frozen=True, order=True)
class RunSpec:
    """One training run of the grid.

    Attributes:
        dataset: registered dataset name.
        method: registered CL method name.
        profile: hyperparameter profile (``paper``, ``fast``, ``smoke``).
        seed: random seed.
        order: task order (0, 1, 2).
        node: ``"t"`` (NODE with time input) or ``"i"`` (without).
        tasks: stop after this many tasks (None: all).
        sim: execute predictions in simulation during evaluation.
        overrides: ``(key, value)`` pairs passed to training as ``--set key=value``
            (hyperparameter studies); part of the run's name so variants never collide.
        config_file: the method's hyperparameter file (``--config``; None: its default, a
            plugin's own or ``baselines/<name>.toml``), stored absolute.
        entry: the row the run counts in when it is not its bare method's: a named entry
            (:mod:`clfd_bench.leaderboard.entries`, whose node and settings it carries) or a
            study's configuration label; None: its method.
    """

    dataset: str
    method: str
    profile: str
    seed: int
    order: int = 0
    node: str = "t"
    tasks: int | None = None
    sim: bool = True
    overrides: tuple[tuple[str, str], ...] = ()
    config_file: str | None = None
    entry: str | None = None

    def __post_init__(self) -> None:
        if self.config_file is not None:
            resolved = str(Path(self.config_file).expanduser().resolve())
            object.__setattr__(self, "config_file", resolved)
        pairs = tuple(sorted((str(k), str(v)) for k, v in self.overrides))
        for key, value in pairs:
            if not (_SAFE.fullmatch(key) and _SAFE.fullmatch(value)):
                raise ValueError(
                    f"override {key}={value!r}: keys and values of a grid run may only use "
                    "letters, digits and . _ + - (they become part of its directory name)"
                )
        object.__setattr__(self, "overrides", pairs)

    @property
    def method_dir(self) -> str:
        """The method's folder name: its name, or for a plugin named by an import spec
        (``package.module:Class``, ``file.py:Class``) the class's ``name``."""
        if ":" not in self.method:
            return self.method
        from clfd_bench.methods import get_method_class

        return get_method_class(self.method).name

    @property
    def label(self) -> str:
        """The leaderboard row the run counts in: its entry's name, else its method's."""
        return self.entry or self.method

    @property
    def name(self) -> str:
        """A short unique name, also the run's directory below ``<out>/runs/``."""
        tasks = f"_k{self.tasks}" if self.tasks is not None else ""
        sim = "" if self.sim else "_nosim"
        sets = "".join(f"_{k}={v}" for k, v in self.overrides)
        return (
            f"{self.dataset}/{self.method_dir}/{self.profile}_node{self.node}"
            f"_o{self.order}_s{self.seed}{tasks}{sim}{sets}"
        )

    def run_dir(self, root: Path) -> Path:
        """The run's directory below ``root/runs``."""
        return Path(root) / "runs" / self.name

    def train_spec(self) -> TrainSpec:
        """What the run trains (:class:`~clfd_bench.harness.run.TrainSpec`)."""
        return TrainSpec(self.method, self.dataset, self.profile, self.seed, self.order,
                         self.node, self.tasks, tuple(self.settings), self.config_file)

    def job(self, root: Path) -> Job:
        """The grid worker's job that performs (or resumes) this run below ``root``."""
        return Job(self.train_spec(), str(self.run_dir(root)), self.sim)

    def worker_argv(self, root: Path) -> list[str]:
        """The command that performs (or resumes) this run below ``root``: a grid worker
        (``python -m clfd_bench.harness.worker JOB``, :mod:`clfd_bench.harness.worker`)."""
        return self.job(root).argv()

    @property
    def settings(self) -> list[str]:
        """The overrides as ``key=value`` strings, as ``--set`` takes them."""
        return [f"{key}={value}" for key, value in self.overrides]

    def config(self, arg_names: dict[str, str] | None = None):
        """The run's resolved configuration (:class:`~clfd_bench.harness.run_config.RunConfig`);
        raises ``ConfigError`` for an unknown key or value before anything is trained
        (``arg_names``: the options run-level values came from, named in its errors)."""
        return self.train_spec().config(arg_names)

    def num_tasks(self) -> int:
        """How many tasks the run learns: ``tasks`` or all of the dataset's."""
        from clfd_bench.data import DATASETS

        total = len(DATASETS[self.dataset].task_names()[self.order])
        return total if self.tasks is None else min(self.tasks, total)

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain data; ``RunSpec(**spec.to_dict())`` gives it back."""
        return asdict(self)


def make_grid(
    dataset: str,
    methods: list[str],
    profile: str,
    seeds: list[int],
    orders: list[int],
    options: GridOptions = GridOptions(),
    configs: dict[str, str] | None = None,
) -> list[RunSpec]:
    """Every (method, seed, order) combination as a :class:`RunSpec`, in a stable order, with
    the node, tasks and simulation of ``options``.

    ``methods`` may name entries (:data:`~clfd_bench.leaderboard.entries.ENTRIES`): their
    runs train the entry's method with the entry's node and settings. ``configs``: method or
    entry name -> its hyperparameter file (``--config METHOD=PATH``).

    Raises:
        ValueError: an empty dimension, or two names whose runs would share directories.
    """
    from clfd_bench.leaderboard.entries import ENTRIES

    if not methods or not seeds or not orders:
        raise ValueError("a grid needs at least one method, one seed and one order")
    specs = []
    tasks, sim = options.tasks, options.sim
    for m, o, s in product(methods, orders, seeds):
        config_file = (configs or {}).get(m)
        entry = ENTRIES.get(m)
        if entry is None:
            specs.append(RunSpec(dataset, m, profile, s, o, options.node, tasks, sim,
                                 config_file=config_file))
        else:
            specs.append(RunSpec(dataset, entry.method, profile, s, o, entry.node, tasks, sim,
                                 entry.settings, config_file, entry=entry.name))
    owners: dict[str, str] = {}
    for spec in specs:
        other = owners.setdefault(spec.name, spec.label)
        if other != spec.label:
            raise ValueError(f"{other!r} and {spec.label!r} in --methods would train the same "
                             f"runs ({spec.name}); a grid needs distinct methods")
    return specs


def run_state(spec: RunSpec, root: Path) -> RunStatus:
    """Where the run of ``spec`` under ``root`` stands (:meth:`clfd_bench.runs.RunDir.status`),
    with what is left to do in words. With simulation, executions by another simulator
    version do not count (the fingerprint is cached per process: :func:`reread_simulator`
    makes the next call read the simulator's files again)."""
    fingerprint = None
    if spec.sim:
        from clfd_bench.execution.fingerprint import sim_fingerprint

        fingerprint = sim_fingerprint()
    return RunDir(spec.run_dir(root)).status(spec.num_tasks(), spec.sim, fingerprint)


def run_status(spec: RunSpec, root: Path) -> str:
    """``"done"``, ``"failed"`` (its last attempt crashed), ``"partial"`` or ``"missing"``
    (:func:`run_state`)."""
    return run_state(spec, root).state


def reread_simulator() -> None:
    """Forgets the cached simulator fingerprint, so the next :func:`run_state` hashes the
    simulator's files as they are now (a file edited while a grid ran is seen)."""
    from clfd_bench.execution.fingerprint import sim_fingerprint

    sim_fingerprint.cache_clear()


def lockstep_key(spec: RunSpec) -> tuple | None:
    """Under which key ``spec`` may train in lockstep with other runs of the same key, or
    None when it gains nothing from it: runs differing only in seed and order, whose every
    model is a NODE integrated by the fused fixed-step RK4 (the losses that
    :func:`~clfd_bench.learning.objective.stack_key` stacks; adaptive solvers and stable
    NODEs would only take turns on one core). Unresolvable configs: None (the run reports
    its error alone)."""
    try:
        config = spec.config()
    except Exception:  # noqa: BLE001 - reported by the run itself
        return None
    if config.node == "s" or not all(
            cfg.solver == "rk4" and cfg.solver_backend == "fused" for _, cfg in config.parts):
        return None
    return (spec.dataset, spec.method, spec.profile, spec.node, spec.tasks, spec.sim,
            spec.overrides, spec.config_file)


def lockstep_batches(specs: list[RunSpec], workers: int, enabled: bool = True
                     ) -> list[list[RunSpec]]:
    """The grid's runs in the processes that run them: runs of one :func:`lockstep_key`
    together, in batches of at most ``ceil(len(specs) / workers)`` (so every worker gets
    work) and :data:`MAX_LOCKSTEP`, split evenly; every other run alone. The order of
    ``specs`` is kept (by each batch's first run). ``enabled=False``: every run alone."""
    if not enabled:
        return [[spec] for spec in specs]
    size = max(1, min(MAX_LOCKSTEP, -(-len(specs) // max(1, workers))))
    groups: dict[object, list[RunSpec]] = {}
    for i, spec in enumerate(specs):
        key = lockstep_key(spec) if size > 1 else None
        groups.setdefault(i if key is None else key, []).append(spec)
    batches = []
    for group in groups.values():
        n = -(-len(group) // size)
        batches += [group[j::n] for j in range(n)]
    position = {spec: i for i, spec in enumerate(specs)}
    return sorted(batches, key=lambda batch: position[batch[0]])
