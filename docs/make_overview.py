"""The guide's overview figure and the small real-photo contact sheet, from outputs of ipm
commands (nothing is rendered here).

    ipm fit examples/golden.png --refine --pixel-size 0.02 --knit knit --out /tmp/golden-fit
    python docs/make_overview.py --fit /tmp/golden-fit           # docs/figures/overview.png

    python -m ipm.benchmarks.real_photos ... --work /tmp/real-photos
    python docs/make_overview.py --contact-sheet /tmp/real-photos/contact_sheet.png
                                                 # docs/figures/real_photos_contact_sheet.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "figures"
#: Height of one yarn strip in the overview (px); the knit patch is two strips high.
STRIP = 170
GAP = 6


def labelled(image: Image.Image, text: str) -> Image.Image:
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=15)
    left, top, right, bottom = draw.textbbox((6, 4), text, font=font)
    draw.rectangle([0, 0, right + 6, bottom + 4], fill=(255, 255, 255))
    draw.text((6, 4), text, fill=(0, 0, 0), font=font)
    return image


def overview(fit: Path, photo: Path) -> Image.Image:
    """photo above fit (the refined render) on the left, the knit patch of the fit on the
    right, two strips high."""
    strip_w = round(STRIP * Image.open(photo).width / Image.open(photo).height)
    shot = labelled(Image.open(photo).convert("RGB").resize((strip_w, STRIP), Image.LANCZOS),
                    "photo")
    refined = labelled(Image.open(fit / "refined.png").convert("RGB")
                       .resize((strip_w, STRIP), Image.LANCZOS), "ipm's fit")
    side = 2 * STRIP + GAP
    patch = Image.open(fit / "knit.png").convert("RGB")
    knit = labelled(patch.resize((round(side * patch.width / patch.height), side),
                                 Image.LANCZOS), "knit patch of the fit")
    out = Image.new("RGB", (strip_w + GAP + knit.width, side), (255, 255, 255))
    out.paste(shot, (0, 0))
    out.paste(refined, (0, STRIP + GAP))
    out.paste(knit, (strip_w + GAP, 0))
    return out


def small_sheet(sheet: Path, width: int = 640) -> Image.Image:
    """The real-photo contact sheet, grey and ``width`` px wide (under 1 MB)."""
    im = Image.open(sheet).convert("L")
    return im.resize((width, round(im.height * width / im.width)), Image.LANCZOS)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fit", type=Path, help="an `ipm fit --refine --knit knit` folder")
    ap.add_argument("--photo", type=Path, default=ROOT / "examples" / "golden.png",
                    help="the photo that fit was made of")
    ap.add_argument("--contact-sheet", type=Path, help="a real_photos run's contact_sheet.png")
    args = ap.parse_args()
    if args.fit:
        overview(args.fit, args.photo).save(OUT / "overview.png", optimize=True)
        print(OUT / "overview.png")
    if args.contact_sheet:
        small_sheet(args.contact_sheet).save(OUT / "real_photos_contact_sheet.png",
                                             optimize=True)
        print(OUT / "real_photos_contact_sheet.png")


if __name__ == "__main__":
    main()
