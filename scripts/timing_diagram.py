"""Draw the verdict suite's timing protocol (docs/methods.md) as docs/img/timing-protocol.svg.

The counts and limits in the drawing are read from the harness (the default settings' rounds and
pairs, the sample length, the confidence and the tie factor), so the figure says what the code
does; run it again when they change and commit the SVG. The output is byte-for-byte reproducible
(fixed hash salt, no date).

    python scripts/timing_diagram.py [--out docs/img/timing-protocol.svg]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, Rectangle

from harness.measure.paired import CONFIDENCE, SAMPLE_S, TIE_FACTOR
from harness.settings import DEFAULT

PINN, RIVAL, WARM = "#d1495b", "#30638e", "#bbbbbb"
OUT = Path(__file__).resolve().parents[1] / "docs" / "img" / "timing-protocol.svg"


def _box(ax, x: float, y: float, w: float, h: float, color: str, text: str = "", **kw) -> None:
    ax.add_patch(Rectangle((x, y), w, h, facecolor=color, edgecolor="white", linewidth=0.8))
    if text:
        ax.text(x + w / 2, y + h / 2, text, ha="center", va="center", color="white", fontsize=7, **kw)


def _group(ax, x: float, y: float, pairs: int, width: float) -> float:
    """One (query, seed) of a round: `pairs` interleaved pairs, the order swapped every pair."""
    for i in range(pairs):
        first, second = (PINN, RIVAL) if i % 2 == 0 else (RIVAL, PINN)
        _box(ax, x, y, width, 0.5, first)
        _box(ax, x + width, y, width, 0.5, second)
        x += 2 * width
    return x


def _arrow(ax, x0: float, y0: float, x1: float, y1: float) -> None:
    ax.add_patch(FancyArrowPatch((x0, y0), (x1, y1), arrowstyle="-|>", mutation_scale=10, color="#444444"))


def draw(out: Path) -> None:
    rounds, pairs = DEFAULT.verdict_rounds, DEFAULT.verdict_pairs
    plt.rcParams.update({"svg.hashsalt": "swingbench", "svg.fonttype": "none", "font.size": 8})
    fig, ax = plt.subplots(figsize=(10, 4.4))
    ax.set_xlim(-0.5, 110.5)
    ax.set_ylim(-1.2, 8.2)
    ax.axis("off")

    # the time line: warm-up, then the rounds, each over every (query, seed) of the case in turn
    y, w = 6.0, 1.2
    seed_a, seed_b = DEFAULT.verdict_seeds[:2]
    ax.text(0, 7.6, "time →", fontsize=8, color="#444444")
    _box(ax, 0, y, 3.5, 0.5, WARM, "PINN")
    _box(ax, 3.5, y, 3.5, 0.5, WARM, "rival")
    ax.text(3.5, y - 0.2, "warm-up:\neach call\nonce, untimed\n(compilation,\ncaches)", ha="center",
            va="top", fontsize=6.5)
    x = 9.0
    for r in range(rounds):
        start = x
        for label in (f"query 1,\nseed {seed_a}", f"query 1,\nseed {seed_b}", None, "last query,\nlast seed"):
            if label is None:
                ax.text(x + 1.5, y + 0.25, "…", ha="center", va="center", fontsize=12)
                x += 3.0
                continue
            end = _group(ax, x, y, pairs, w)
            ax.text((x + end) / 2, y - 0.2, label, ha="center", va="top", fontsize=6.5)
            x = end + 0.8
        ax.annotate("", (start, y + 0.85), (x - 0.8, y + 0.85),
                    arrowprops={"arrowstyle": "<->", "color": "#444444", "linewidth": 0.8})
        ax.text((start + x - 0.8) / 2, y + 1.0, f"round {r + 1} of {rounds}", ha="center", va="bottom")
        if r + 1 < rounds:
            ax.text(x + 2.2, y + 0.25, "minutes\nlater", ha="center", va="center", fontsize=7)
            x += 4.4

    # one sample, enlarged
    ax.text(9.0, 4.35, f"{pairs} interleaved pairs per (query, seed) and round: "
            "PINN, rival; rival, PINN; … (the order swapped every pair)", fontsize=7.5)
    _box(ax, 9.0, 3.2, 9.0, 0.5, PINN, "one sample")
    ax.text(18.8, 3.45, f"= the mean of back-to-back calls lasting at least {SAMPLE_S * 1e3:g} ms together "
            "(one call when a call is slower)", va="center", fontsize=7.5)

    # from the samples to the label
    steps = [
        f"{rounds * pairs} samples of each side\nper query and seed",
        "ratio = median(rival)\n/ median(PINN)\n(> 1: the PINN is faster)",
        f"{CONFIDENCE:.0%} interval:\npercentile bootstrap\nover the paired samples",
        (f"label: PINN faster if\nthe interval lies above\n{TIE_FACTOR:g}x, classical faster\nif below "
         f"1/{TIE_FACTOR:g}, otherwise tie"),
        "over seeds: a side only\nwhen every seed says it",
    ]
    bx, bw, gap = 0.0, 20.0, 2.5
    for i, text in enumerate(steps):
        ax.add_patch(Rectangle((bx, -0.6), bw, 2.3, facecolor="#f2f2f2", edgecolor="#888888", linewidth=0.8))
        ax.text(bx + bw / 2, 0.55, text, ha="center", va="center", fontsize=7.5)
        if i + 1 < len(steps):
            _arrow(ax, bx + bw + 0.2, 0.55, bx + bw + gap - 0.2, 0.55)
        bx += bw + gap

    handles = [Rectangle((0, 0), 1, 1, facecolor=c) for c in (PINN, RIVAL, WARM)]
    ax.legend(handles, ["PINN sample", "rival sample", "untimed"], loc="upper right", frameon=False,
              ncol=3, fontsize=7.5)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, format="svg", bbox_inches="tight", metadata={"Date": None})
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    draw(parser.parse_args().out)


if __name__ == "__main__":
    main()
