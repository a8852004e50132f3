"""Named leaderboard entries: a CL method with a fixed target network and settings.

An entry is a row of the leaderboard that is not a bare method: e.g. the follow-up paper's
(Auddy et al., "Scalable and efficient continual learning from demonstration via a
hypernetwork-generated stable dynamics model") headline configurations, a hypernetwork
generating the stable NODE (``--node s``) trained with the stochastic output regulariser
(``hnet_reg = "sampled"``, its ``calc_fix_target_reg_stochastic``). ``--methods`` takes an
entry's name wherever it takes a method's: ``--methods hn,chn,hn-snode,chn-snode`` compares
the paper's hypernetworks with the follow-up's in one table.

An entry's NODE variant and settings win over the grid's ``--node`` (so the row is always
the configuration its name says); everything else (profile, seeds, orders, tasks, the
method's hyperparameter file) comes from the grid. Its runs live in the method's folder,
named by variant and settings (``runs/<dataset>/hn/fast_nodes_o0_s0_hnet_reg=sampled``), so
a grid with both ``hn`` and ``hn-snode`` never mixes them.

No heavy imports: the command line lists the entries without loading torch.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ENTRIES", "Entry", "entry_help"]


@dataclass(frozen=True)
class Entry:
    """One named configuration.

    Attributes:
        name: what ``--methods`` takes and the row is called (lower case).
        method: the registered CL method it trains.
        node: the NODE variant (``t``, ``i``, ``s``); overrides the grid's ``--node``.
        settings: ``(key, value)`` pairs given to training as ``--set key=value``.
        source: where the configuration comes from, one line (tables print it).
    """

    name: str
    method: str
    node: str
    settings: tuple[tuple[str, str], ...]
    source: str

    def describe(self) -> str:
        """``HN-SNODE = HN generating sNODE, hnet_reg=sampled (source)``."""
        from clfd_bench.node_variants import node_label

        sets = "".join(f", {k}={v}" for k, v in self.settings)
        return (f"{self.name.upper()} = {self.method.upper()} with {node_label(self.node)}"
                f"{sets} ({self.source})")


_FOLLOW_UP = "Auddy et al.'s follow-up: stable NODE, stochastic regulariser"

ENTRIES: dict[str, Entry] = {
    e.name: e
    for e in (
        Entry("hn-snode", "hn", "s", (("hnet_reg", "sampled"),), _FOLLOW_UP),
        Entry("chn-snode", "chn", "s", (("hnet_reg", "sampled"),), _FOLLOW_UP),
    )
}
"""Entry name -> :class:`Entry`. The stochastic regulariser's number of sampled earlier
tasks is the profile's ``hnet_reg_samples`` (1 in every profile: the released code takes it
from ``--num_regs`` and publishes no value)."""


def entry_help() -> str:
    """One line for ``--methods`` help: the entries' names."""
    return "named entries: " + ", ".join(ENTRIES)
