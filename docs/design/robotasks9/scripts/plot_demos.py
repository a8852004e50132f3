"""Plots of the 5 new RoboTasks9 tasks: grasp-point paths (3 views), z(t), speed(t), rotation
angle from the start pose (t), hand axes along demo 0.
Output: $RT9_OUT/plots/<task>.png (default results/robotasks9/plots/<task>.png in the repo).
Run from the repo root: nice -n 19 python docs/design/robotasks9/scripts/plot_demos.py"""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from common import HZ, NEW, grasp, mats, out_dir, rot, tasks

PLOTS = out_dir() / "plots"
PLOTS.mkdir(exist_ok=True)
T = tasks()
for name in NEW:
    t = T[name]
    P, Q = t.positions, t.quaternions
    G = grasp(P, Q)
    M = mats(Q)
    time = np.arange(P.shape[1]) / HZ
    fig, ax = plt.subplots(2, 3, figsize=(17, 10))
    for n in range(len(P)):
        c = f"C{n}"
        for k, (i, j) in enumerate([(0, 1), (0, 2), (1, 2)]):
            ax[0, k].plot(G[n, :, i], G[n, :, j], c, lw=1, label=f"d{n}" if k == 0 else None)
            ax[0, k].plot(G[n, 0, i], G[n, 0, j], "o", color=c, ms=4)
        ax[1, 0].plot(time, G[n, :, 2], c, lw=1)
        v = np.linalg.norm(np.diff(G[n], axis=0), axis=1) * HZ
        ax[1, 1].plot(time[1:], np.convolve(np.pad(v, 4, mode="edge"), np.ones(9) / 9, "valid"),
                      c, lw=1)
        rr = rot(Q[n])
        ax[1, 2].plot(time, np.degrees((rr * rr[0].inv()).magnitude()), c, lw=1)
    # hand axes along demo 0 on the y-z view (every 50 samples): z axis red, x blue, y green
    for s in range(0, P.shape[1], 50):
        for a, col in ((0, "b"), (1, "g"), (2, "r")):
            ax[0, 2].arrow(G[0, s, 1], G[0, s, 2], 0.04 * M[0, s, 1, a], 0.04 * M[0, s, 2, a],
                           color=col, width=0.0008)
            ax[0, 1].arrow(G[0, s, 0], G[0, s, 2], 0.04 * M[0, s, 0, a], 0.04 * M[0, s, 2, a],
                           color=col, width=0.0008)
    for k, lab in enumerate(["x-y (top)", "x-z", "y-z (arrows: demo0 hand x b, y g, z r)"]):
        ax[0, k].set_title(lab)
        ax[0, k].set_aspect("equal")
        ax[0, k].grid(True)
    ax[0, 0].legend(fontsize=7)
    ax[1, 0].set_title("grasp z (m) vs t (s)")
    ax[1, 1].set_title("grasp speed m/s")
    ax[1, 2].set_title("rotation from start pose (deg)")
    for a in ax[1]:
        a.grid(True)
    fig.suptitle(name)
    fig.tight_layout()
    fig.savefig(PLOTS / f"{name}.png", dpi=70)
    plt.close(fig)
print("ok")
