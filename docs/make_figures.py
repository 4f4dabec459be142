"""Figures of the docs that need only the generator (no renderer).

    python docs/make_figures.py   # writes docs/figures/helix_mapping.png and flyaways.png
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ipm.fibers import FiberKind, FiberSet
from ipm.generator import LOOP_D_UNIT_MM, Level, generate, hair, levels_of, loop, raw_yarn
from ipm.measure import core_radius, flyaway_reach
from ipm.presets import preset
from ipm.sketch import side_view

OUT = Path(__file__).parent / "figures"


def helix_mapping() -> Image.Image:
    """Paper Fig. 5, exaggerated: one ply mapped onto a steep helix by shifting orthogonal
    to the global axis (Zhao et al.) and by the local-frame transformation (ours).  Grey:
    fibers; red: the fiber vertices of a few template heights, i.e. ply cross-sections."""
    levels = [Level(60, 0.6, -40.0), Level(1, 1.2, 4.0)]
    panels = []
    for mapping in ("global", "local"):
        fibers, _ = raw_yarn(levels, np.random.default_rng(0), length=6.0, mapping=mapping)
        f, v = fibers.shape[:2]
        fs = FiberSet(points=fibers.reshape(-1, 3).astype(np.float32),
                      offsets=np.arange(f + 1) * v, radii=np.full((f, 2), 0.01, np.float32),
                      kind=np.zeros(f, np.uint8), ply=np.zeros(f, np.int16))
        img = side_view(fs, 8.0, 4.4, 60, colors=[(170, 170, 170)] * f)
        draw = ImageDraw.Draw(img)
        for i in range(v // 8, v, v // 6):
            for _, y, z in fibers[:, i]:
                u, w = (z + 4.0) * 60, (2.2 - y) * 60
                draw.ellipse([u - 2, w - 2, u + 2, w + 2], fill=(200, 30, 30))
        title = "global-axis shift (Zhao et al.)" if mapping == "global" else \
            "local coordinate frame (ours)"
        draw.text((8, 6), title, fill=(0, 0, 0))
        panels.append(img)
    out = Image.new("RGB", (panels[0].width * 2 + 10, panels[0].height), (255, 255, 255))
    out.paste(panels[0], (0, 0))
    out.paste(panels[1], (panels[0].width + 10, 0))
    return out


def flyaways(name: str = "golden", seed: int = 1) -> None:
    """The paper's Fig. 6 (flyaway generation) on a real segment of ``name``, and the whole
    yarn's flyaways, both as distance from the yarn axis against z (a side view in which
    "how far out" reads directly): a) the copied fiber segment, b) the hair squeezed along
    the axis and mirrored about its root, c) turned by beta about the far end's radial axis,
    d) the loop (x halved, arch 0.1 d mm); right: every flyaway of the yarn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = preset(name)
    rng = np.random.default_rng(seed)
    core, _ = raw_yarn(levels_of(p), rng)
    fiber = core[int(np.argmax(np.hypot(core[:, 0, 0], core[:, 0, 1])))]  # an outer fiber
    seg = fiber[130:130 + int(p.l_hair / 0.1)]
    squeezed = seg - seg[0]
    squeezed[:, 2] /= 1 + 1.5 * p.s
    squeezed[:, 0] *= -1
    steps = [("a) copied segment", seg, "0.5"), ("b) squeezed, mirrored", seg[0] + squeezed,
                                                   "tab:blue"),
             (f"c) hair: turned by beta = {p.beta:.2f}", hair(seg, p.beta, p.s), "tab:blue"),
             (f"d) loop: arch 0.1 d = {LOOP_D_UNIT_MM * p.d_mean:.2f} mm",
              loop(seg, LOOP_D_UNIT_MM * p.d_mean), "tab:orange")]
    fs = generate(p, seed)
    fig = plt.figure(figsize=(13, 4.2))
    grid = fig.add_gridspec(2, 4, width_ratios=[1, 1, 1, 1])
    for i, (title, pts, color) in enumerate(steps):
        ax = fig.add_subplot(grid[i // 2, i % 2])
        ax.plot(fiber[100:200, 2], np.hypot(fiber[100:200, 0], fiber[100:200, 1]), color="0.8",
                lw=1)
        ax.plot(pts[:, 2], np.hypot(pts[:, 0], pts[:, 1]), color=color, lw=1.6)
        ax.set_title(title, fontsize=9)
        ax.set_ylim(0, 1.2)
        ax.tick_params(labelsize=7)
    ax = fig.add_subplot(grid[:, 2:])
    radius = core_radius(fs)
    for f in range(fs.num_fibers):
        pts = fs.fiber(f)
        kind = fs.kind[f]
        if kind == FiberKind.CORE and f % 4:
            continue
        color = {FiberKind.CORE: "0.8", FiberKind.HAIR: "tab:blue",
                 FiberKind.LOOP: "tab:orange"}[FiberKind(kind)]
        ax.plot(pts[:, 2], np.hypot(pts[:, 0], pts[:, 1]), color=color, lw=0.5)
    ax.axhline(radius, color="k", lw=0.8, ls="--")
    reach = np.median(flyaway_reach(fs))
    ax.set_title(f"{name}: every flyaway (blue hairs, orange loops); dashed: core radius "
                 f"(p95), median reach {reach:.2f} mm", fontsize=9)
    ax.set_xlim(-10, 10)
    ax.set_xlabel("z along the yarn (mm)")
    ax.set_ylabel("distance from the yarn axis (mm)")
    fig.tight_layout()
    fig.savefig(OUT / "flyaways.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    OUT.mkdir(exist_ok=True)
    helix_mapping().save(OUT / "helix_mapping.png")
    flyaways()
    print(OUT / "helix_mapping.png", OUT / "flyaways.png")
