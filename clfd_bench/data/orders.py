"""Task orders: the paper's appendix table "Task orders" (orders 0, 1, 2)."""

from __future__ import annotations

__all__ = ["TASK_ORDERS"]

_LASA = (
    (
        "Angle", "BendedLine", "CShape", "DoubleBendedLine", "GShape", "heee", "JShape_2",
        "JShape", "Khamesh", "Leaf_1", "Leaf_2", "Line", "LShape", "NShape", "PShape",
        "RShape", "Saeghe", "Sharpc", "Sine", "Snake", "Spoon", "Sshape", "Trapezoid",
        "Worm", "WShape", "Zshape",
    ),
    (
        "Spoon", "Sine", "Zshape", "NShape", "PShape", "heee", "Angle", "Khamesh", "Line",
        "LShape", "JShape_2", "WShape", "Leaf_2", "RShape", "JShape", "Sharpc", "Snake",
        "DoubleBendedLine", "Saeghe", "Worm", "Leaf_1", "GShape", "BendedLine", "Sshape",
        "CShape", "Trapezoid",
    ),
    (
        "BendedLine", "RShape", "Trapezoid", "WShape", "PShape", "heee", "Sshape", "Line",
        "JShape", "DoubleBendedLine", "Sine", "GShape", "Sharpc", "LShape", "Saeghe",
        "Khamesh", "CShape", "Zshape", "JShape_2", "Snake", "Angle", "Worm", "Leaf_2",
        "Spoon", "NShape", "Leaf_1",
    ),
)  # fmt: skip

_HELLOWORLD = (
    ("h", "e", "l", "o", "w", "r", "d"),
    ("l", "d", "h", "o", "w", "r", "e"),
    ("o", "w", "l", "h", "e", "d", "r"),
)

_ROBOTASKS = (
    ("openbox", "bottle2shelf", "platestandingtolying", "pouring"),
    ("platestandingtolying", "openbox", "bottle2shelf", "pouring"),
    ("pouring", "openbox", "platestandingtolying", "bottle2shelf"),
)

TASK_ORDERS: dict[str, tuple[tuple[str, ...], ...]] = {
    "lasa": _LASA,
    "helloworld": _HELLOWORLD,
    "robotasks": _ROBOTASKS,
}
"""dataset -> orders; each order lists task names in training order. RoboTasks9 is not in
the paper's table: its only order (0) is its upstream sequence file's."""
