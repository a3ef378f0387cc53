"""Draw the figures of docs/branching.md:  python docs/figures.py  (writes docs/branching.png)."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

import contourmesh  # noqa: E402
from contourmesh.meshes import atomic_write  # noqa: E402


def y_branch() -> np.ndarray:
    """A trunk that forks into two arms: one contour below, two above."""
    z, y, x = np.mgrid[0:14, 0:24, 0:24]
    trunk = ((x - 11.5) ** 2 + (y - 11.5) ** 2 < 30) & (z < 7)
    arm1 = ((x - 6.5 + 0.0 * z) ** 2 + (y - 11.5) ** 2 < 14) & (z >= 6)
    arm2 = ((x - 16.5) ** 2 + (y - 11.5) ** 2 < 14) & (z >= 6)
    return trunk | arm1 | arm2


def draw(ax, m, title):
    tri = m.vertices[m.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    shade = 0.35 + 0.65 * np.clip(n @ np.array([0.4, -0.5, 0.75]), 0, 1)
    flat = np.abs(n[:, 2]) > 0.999
    colors = np.where(flat[:, None], [0.95, 0.55, 0.2], [0.3, 0.55, 0.85]) * shade[:, None]
    ax.add_collection3d(Poly3DCollection(tri, facecolors=colors, edgecolors=(0, 0, 0, 0.15), linewidths=0.2))
    lo, hi = m.vertices.min(0), m.vertices.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.view_init(elev=18, azim=-60)
    ax.set_title(title, fontsize=9)
    ax.set_axis_off()


def main():
    vol = y_branch()
    fig = plt.figure(figsize=(10, 4.6))
    for i, (pol, title) in enumerate([("mlp", "MLP polygons, paper's bands"), ("none", "contours themselves")]):
        m = contourmesh.mesh(vol, polygon=pol)
        chk = m.checks()
        ax = fig.add_subplot(1, 2, i + 1, projection="3d")
        draw(ax, m, f"{title}\n{m.meta['band_joins']} band joins, {m.meta['bridged_joins']} bridged, "
                    f"{m.meta['exact_joins']} exact join(s); "
                    f"closed={chk['watertight']}, genus {chk['genus']:.0f}")
    fig.suptitle("Branching: one contour below, two above. The fork is one band from the trunk's polygon\n"
                 "to the arms' polygons bridged into one ring; flat faces (orange) are the end caps", fontsize=9)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    atomic_write(Path(__file__).with_name("branching.png"), buf.getvalue())


if __name__ == "__main__":
    main()
