"""Borderline executions: per env and check, the executions whose measured value lies nearest
the check's bound, on the passing and on the failing side (pure selection, no simulation).

Input is a list of :class:`Execution` (one executed prediction with its env's final checks,
:class:`clfd_bench.envs.checks.Check`); :func:`select_borderline` returns, for every env and
every numeric check, up to ``per_side`` :class:`Pick` on each side:

- *passing side*: ``margin >= 0``, smallest margin first (:attr:`Pick.decisive` says whether
  the execution succeeded, :attr:`Pick.also_failed` what else failed).
- *failing side*: ``margin < 0``, smallest ``|margin|`` first; executions that fail *only this
  check* are preferred (their failure is this check's alone); the others name what else
  failed (:attr:`Pick.also_failed`).

Left out: yes/no checks (:func:`is_flag`: a flag has no distance to its bound), values that
could not be measured (``margin = -inf``), and executions whose checks do not describe a
whole episode (:attr:`Execution.complete` false: the rollout ended early on a motion limit,
tracking, reach, collision or a decided failure). Executions sharing a ``key`` (the same
prediction evaluated after several tasks) count once.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence

from clfd_bench.envs.checks import Check

__all__ = ["Borderline", "Execution", "Pick", "is_flag", "numeric_check_names",
           "select_borderline"]

#: The sides of a bound.
SIDES = ("pass", "fail")


@dataclasses.dataclass(frozen=True)
class Execution:
    """One executed prediction and the env's final checks.

    Attributes:
        env_id: the env it ran in (e.g. ``"clfd/HelloWorld-h-v2"``).
        key: identifies the executed prediction (the rollout-cache key); equal keys are the
            same execution.
        checks: the env's checks at the end of the episode, in the env's order.
        complete: the checks describe the whole episode (False when the rollout ended early).
        success: the env's success decision.
        label: free data for the caller (run, method, task, demo, after which task), carried
            through to the picks; not used by the selection.
    """

    env_id: str
    key: str
    checks: tuple[Check, ...]
    complete: bool = True
    success: bool | None = None
    label: dict = dataclasses.field(default_factory=dict, compare=False, hash=False)

    def check(self, name: str) -> Check | None:
        """The check called ``name`` (None when the env did not report it)."""
        for c in self.checks:
            if c.name == name:
                return c
        return None

    def failed(self) -> list[str]:
        """Names of the checks that did not pass, in order."""
        return [c.name for c in self.checks if not c.passed]


@dataclasses.dataclass(frozen=True)
class Pick:
    """One execution chosen for a check's side.

    Attributes:
        execution: the execution.
        check: its check (the one this pick is for).
        side: ``"pass"`` or ``"fail"``.
        decisive: this check alone decides the execution's verdict: on the passing side every
            check passes, on the failing side this is the only failed check.
        also_failed: the other checks that failed (empty when ``decisive`` on the failing side).
    """

    execution: Execution
    check: Check
    side: str
    decisive: bool
    also_failed: tuple[str, ...]

    @property
    def margin(self) -> float:
        """The check's signed margin (>= 0 passes)."""
        return self.check.margin


@dataclasses.dataclass(frozen=True)
class Borderline:
    """The picks of one env's check.

    Attributes:
        env_id, check: which.
        passing, failing: up to ``per_side`` picks each, nearest the bound first (failing:
            the decisive ones first; see the module docstring).
        candidates: executions with a measured value of this check (pass, fail).
    """

    env_id: str
    check: str
    passing: tuple[Pick, ...]
    failing: tuple[Pick, ...]
    candidates: tuple[int, int]


def is_flag(check: Check) -> bool:
    """A yes/no condition (:meth:`Check.flag`): value 0 or 1 against bound 1 with ``>=``."""
    return (check.op == ">=" and check.bound == 1.0 and check.unit == ""
            and check.value in (0.0, 1.0))


def numeric_check_names(executions: Iterable[Execution]) -> dict[str, list[str]]:
    """Per env id, the names of its numeric checks in the env's order: every reported check
    except those that are yes/no flags (:func:`is_flag`) in every execution."""
    seen: dict[str, dict[str, bool]] = {}
    for ex in executions:
        names = seen.setdefault(ex.env_id, {})
        for c in ex.checks:
            numeric = c.value is not None and not is_flag(c)
            names[c.name] = names.get(c.name, False) or numeric
    return {env: [n for n, numeric in names.items() if numeric] for env, names in seen.items()}


def select_borderline(executions: Sequence[Execution], per_side: int = 2
                      ) -> list[Borderline]:
    """The executions nearest each numeric check's bound, on both sides.

    Args:
        executions: executed predictions with their final checks (any order; duplicates by
            ``key`` count once, the first kept).
        per_side: picks per side (>= 1).

    Returns:
        One :class:`Borderline` per env and numeric check, envs in order of first appearance,
        checks in the env's order.
    """
    if per_side < 1:
        raise ValueError(f"per_side must be >= 1, got {per_side}")
    unique: dict[str, Execution] = {}
    for ex in executions:
        if ex.complete and ex.key not in unique:
            unique[ex.key] = ex
    pool = list(unique.values())
    out: list[Borderline] = []
    for env_id, names in numeric_check_names(pool).items():
        in_env = [ex for ex in pool if ex.env_id == env_id]
        for name in names:
            passing: list[Pick] = []
            failing: list[Pick] = []
            for ex in in_env:
                c = ex.check(name)
                if c is None or not math.isfinite(c.margin):
                    continue
                others = tuple(n for n in ex.failed() if n != name)
                side = "pass" if c.passed else "fail"
                pick = Pick(ex, c, side, decisive=not others, also_failed=others)
                (passing if c.passed else failing).append(pick)
            # Nearest the bound (failing: decisive first); the key breaks ties.
            passing.sort(key=lambda p: (p.margin, p.execution.key))
            failing.sort(key=lambda p: (not p.decisive, -p.margin, p.execution.key))
            out.append(Borderline(env_id, name, tuple(passing[:per_side]),
                                  tuple(failing[:per_side]), (len(passing), len(failing))))
    return out
