"""Screenshot swath reports for the docs: ``python docs/screenshots.py NAME=path/report.html[@TOP] ...``.

Each report is rendered by headless Chromium (Debian's ``chromium``) and saved as
``docs/img/NAME.png``, 1400 x 1000 pixels from ``TOP`` pixels down the page (default 0: the
warnings and the summary; about 960 on a report with two warnings: its 3D view), reduced to a
256-colour palette so that it stays under 300 kB.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

IMG = Path(__file__).resolve().parent / "img"
CHROMIUM = ["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars",
            "--virtual-time-budget=8000"]
WIDTH, HEIGHT = 1400, 1000


def shoot(report: Path, out: Path, top: int = 0) -> int:
    """Render ``report`` to ``out`` (PNG, palette), ``top`` pixels down the page; returns its size in bytes."""
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "shot.png"
        # a window tall enough for the part wanted, cut afterwards: a page scrolled to an anchor
        # leaves the 3D view blank in headless Chromium
        subprocess.run([*CHROMIUM, f"--window-size={WIDTH},{HEIGHT + top}", f"--screenshot={raw}",
                        report.resolve().as_uri()], check=True, capture_output=True, timeout=180)
        shot = Image.open(raw).convert("RGB").crop((0, top, WIDTH, top + HEIGHT))
        shot.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
    return out.stat().st_size


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        name, path = arg.split("=", 1)
        path, _, top = path.partition("@")
        size = shoot(Path(path), IMG / f"{name}.png", int(top or 0))
        sys.stdout.write(f"{name}.png: {size / 1e3:.0f} kB\n")
