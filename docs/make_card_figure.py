"""The guide's figure of one yarn photographed on four cards, black to white: each photo
(`ipm render --card`) beside the render of its fit (`ipm fit --refine`, shown on the
photo's card and defocus as the fit shows it).  Runs the ipm commands into ``--work``.

    python docs/make_card_figure.py --work /tmp/cards    # docs/figures/cards.png
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from make_overview import GAP, OUT, labelled
from PIL import Image

#: The scene's card albedo times 1, 3, 10 and 30 (white).
CARDS = (0.03, 0.09, 0.3, 0.9)
#: Height of one photo strip (px).
STRIP = 150


def ipm(*args) -> None:
    subprocess.run([sys.executable, "-m", "ipm", *map(str, args)], check=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="folder for the photos and fits")
    ap.add_argument("--preset", default="golden")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    rows = []
    for card in CARDS:
        photo = args.work / f"card{card:g}.png"
        fit = args.work / f"fit{card:g}"
        if not photo.exists():
            ipm("render", "--preset", args.preset, "--card", card, "--scale", 0.5, "-o", photo)
        if not (fit / "params.json").exists():
            ipm("fit", photo, "--refine", "--out", fit)
        shot = Image.open(photo).convert("RGB")
        width = round(STRIP * shot.width / shot.height)
        pair = [labelled(shot.resize((width, STRIP), Image.LANCZOS),
                         f"photo, card albedo {card:g}"),
                labelled(Image.open(fit / "refined.png").convert("RGB").resize(
                    (width, STRIP), Image.LANCZOS), "fit (ipm fit --refine)")]
        rows.append(pair)
    width = rows[0][0].width
    sheet = Image.new("RGB", (2 * width + GAP, len(rows) * (STRIP + GAP) - GAP), "white")
    for i, pair in enumerate(rows):
        for j, img in enumerate(pair):
            sheet.paste(img, (j * (width + GAP), i * (STRIP + GAP)))
    sheet.save(OUT / "cards.png", optimize=True)
    print(OUT / "cards.png")


if __name__ == "__main__":
    main()
