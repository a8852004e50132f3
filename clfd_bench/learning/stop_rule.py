"""The stop rule on the training loss (``stop_window``, ``stop_rel``, ``stop_decays`` of
:class:`~clfd_bench.learning.part_config.PartConfig`): train a task until its loss stops
improving rather than for a fixed number of iterations (which stays the cap).

The smoothed loss is the mean task loss over consecutive windows of ``stop_window``
iterations, the first starting at ``start`` (the end of the learning-rate warm-up and of the
batch horizon's growth: before them the losses of different iterations are on different
horizons and step sizes, so not comparable). At the end of each window its mean ``m`` is
compared with the best earlier window's ``b``: ``m < (1 - stop_rel) * b`` is progress;
anything else is a plateau. The first ``stop_decays`` plateaus divide the learning rate by
:data:`DECAY` (the loss usually falls again at the lower rate); the next one stops the task.

Pure Python (no torch), deterministic: the same losses give the same decisions.
"""

from __future__ import annotations

__all__ = ["DECAY", "StopRule"]

DECAY = 10.0
"""What a plateau divides the learning rate by, while ``stop_decays`` allows."""


class StopRule:
    """Decides, from the loss of every iteration, when to lower the learning rate and when to
    stop (module docstring).

    Args:
        window: iterations per smoothed-loss window (>= 1).
        rel: relative improvement a window needs over the best earlier one, in [0, 1).
        decays: plateaus that lower the learning rate before one stops the task (>= 0).
        start: iteration (0-based) the first window begins at; earlier losses are ignored.

    Attributes:
        lr_scale: the factor on the scheduled learning rate (``DECAY ** -decays_used``).
        stopped_at: the number of iterations run when the rule stopped the task (None: not
            stopped).
        best: the lowest window mean so far (None before the first window ends).
    """

    def __init__(self, window: int, rel: float, decays: int = 0, start: int = 0):
        if window < 1 or not 0.0 <= rel < 1.0 or decays < 0 or start < 0:
            raise ValueError(f"StopRule needs window >= 1, 0 <= rel < 1, decays >= 0 and "
                             f"start >= 0, got {window}, {rel}, {decays}, {start}")
        self.window, self.rel, self.decays, self.start = window, rel, decays, start
        self.lr_scale = 1.0
        self.stopped_at: int | None = None
        self.best: float | None = None
        self._sum = 0.0
        self._count = 0
        self._decays_used = 0

    def state(self) -> dict[str, float | int | None]:
        """Everything :meth:`update` has accumulated, as plain data (a task's snapshot)."""
        return {"lr_scale": self.lr_scale, "stopped_at": self.stopped_at, "best": self.best,
                "sum": self._sum, "count": self._count, "decays_used": self._decays_used}

    def load_state(self, state: dict[str, float | int | None]) -> None:
        """Continue from :meth:`state`'s ``state`` (same window, rel, decays and start)."""
        self.lr_scale = float(state["lr_scale"])
        self.stopped_at = None if state["stopped_at"] is None else int(state["stopped_at"])
        self.best = None if state["best"] is None else float(state["best"])
        self._sum, self._count = float(state["sum"]), int(state["count"])
        self._decays_used = int(state["decays_used"])

    def update(self, iteration: int, loss: float) -> bool:
        """Record the loss of ``iteration`` (0-based, called once per iteration in order);
        True when training should stop after it (then :attr:`stopped_at` is
        ``iteration + 1``). May lower :attr:`lr_scale`."""
        if self.stopped_at is not None:
            return True
        if iteration < self.start:
            return False
        self._sum += loss
        self._count += 1
        if self._count < self.window:
            return False
        mean = self._sum / self._count
        self._sum, self._count = 0.0, 0
        if self.best is None or mean < (1.0 - self.rel) * self.best:
            self.best = mean
            return False
        self.best = min(self.best, mean)
        if self._decays_used < self.decays:
            self._decays_used += 1
            self.lr_scale = DECAY ** -self._decays_used
            return False
        self.stopped_at = iteration + 1
        return True
