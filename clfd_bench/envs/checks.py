"""`Check`: one success criterion's measured value against its bound.

Every env reports the checks behind its success decision in ``info["checks"]`` (a list of
:meth:`Check.to_json` dicts, in the order the env evaluates them), so a report can say which
check failed and by how much, and the borderline gallery can find the executions nearest each
bound. A yes/no condition (held, no contact) is a check too: :meth:`Check.flag`.

Conventions: ``value`` and ``bound`` in ``unit`` (SI: m, deg, N, or "" for counts and
fractions); ``op`` is the comparison that passes (``"<="``: at most the bound, ``">="``: at
least it). ``margin`` is signed: positive on the passing side, so the verdicts nearest a bound
are those with the smallest ``abs(margin)``. A check whose value could not be measured (no ink
at all, a prop that never left the gripper) carries ``value=None`` and fails.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

__all__ = ["OPS", "Check", "check_from_json", "checks_json", "failed_checks"]

#: The comparisons a check may pass by.
OPS = ("<=", ">=")


@dataclasses.dataclass(frozen=True)
class Check:
    """One criterion: ``value op bound`` passes.

    Attributes:
        name: short identifier, unique within an env (e.g. ``"goal"``, ``"release_distance"``).
        value: the measured value, or None when it could not be measured (then it fails).
        bound: the threshold it is compared with.
        op: ``"<="`` or ``">="``.
        unit: unit of value and bound (``"m"``, ``"deg"``, ``"N"``, ``""``).
        note: optional short text (what was measured), shown in reports.
    """

    name: str
    value: float | None
    bound: float
    op: str = "<="
    unit: str = ""
    note: str = ""

    def __post_init__(self) -> None:
        if self.op not in OPS:
            raise ValueError(f"Check {self.name!r}: op {self.op!r} is not one of {OPS}")
        if not math.isfinite(float(self.bound)):
            raise ValueError(f"Check {self.name!r}: bound {self.bound!r} is not finite")

    @classmethod
    def flag(cls, name: str, ok: bool, note: str = "") -> Check:
        """A yes/no condition as a check: value 1.0 (yes) or 0.0 (no) against bound 1.0."""
        return cls(name, 1.0 if ok else 0.0, 1.0, ">=", "", note)

    @property
    def passed(self) -> bool:
        """True when the value is measured, finite and on the passing side of the bound."""
        if self.value is None or not math.isfinite(float(self.value)):
            return False
        if self.op == "<=":
            return float(self.value) <= self.bound
        return float(self.value) >= self.bound

    @property
    def margin(self) -> float:
        """bound - value for ``<=``, value - bound for ``>=`` (>= 0 passes); -inf when the
        value is missing or not finite."""
        if self.value is None or not math.isfinite(float(self.value)):
            return -math.inf
        v = float(self.value)
        return self.bound - v if self.op == "<=" else v - self.bound

    def describe(self) -> str:
        """``"goal_distance 0.0112 m > 0.01 m"`` style text (the failing comparison when it
        fails)."""
        if self.value is None:
            return f"{self.name} not measured ({self.note})" if self.note else \
                f"{self.name} not measured"
        unit = f" {self.unit}" if self.unit else ""
        if self.passed:
            shown = self.op
        else:
            shown = ">" if self.op == "<=" else "<"
        return f"{self.name} {float(self.value):.4g}{unit} {shown} {self.bound:.4g}{unit}"

    def to_json(self) -> dict[str, Any]:
        """JSON-safe dict (a non-finite value becomes None) with ``passed`` added."""
        value = self.value
        if value is not None and not math.isfinite(float(value)):
            value = None
        return {"name": self.name, "value": None if value is None else float(value),
                "bound": float(self.bound), "op": self.op, "unit": self.unit,
                "note": self.note, "passed": self.passed}


def check_from_json(d: Mapping[str, Any]) -> Check:
    """Inverse of :meth:`Check.to_json` (``passed`` is recomputed, not read)."""
    return Check(str(d["name"]), None if d.get("value") is None else float(d["value"]),
                 float(d["bound"]), str(d.get("op", "<=")), str(d.get("unit", "")),
                 str(d.get("note", "")))


def checks_json(checks: Iterable[Check]) -> list[dict[str, Any]]:
    """``[c.to_json() for c in checks]``: what envs put in ``info["checks"]``."""
    return [c.to_json() for c in checks]


def failed_checks(checks: Sequence[Check]) -> list[str]:
    """Names of the checks that did not pass, in order."""
    return [c.name for c in checks if not c.passed]
