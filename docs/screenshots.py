"""Screenshot swath reports for the docs: ``python docs/screenshots.py NAME=path/report.html ...``.

Each report is rendered by headless Chromium (Debian's ``chromium``) at 1400 x 1000 and saved as
``docs/img/NAME.png``, reduced to a 256-colour palette so that it stays under 300 kB.
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
            "--virtual-time-budget=8000", "--window-size=1400,1000"]


def shoot(report: Path, out: Path) -> int:
    """Render ``report`` to ``out`` (PNG, palette); returns its size in bytes."""
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "shot.png"
        subprocess.run([*CHROMIUM, f"--screenshot={raw}", report.resolve().as_uri()], check=True,
                       capture_output=True, timeout=180)
        Image.open(raw).convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
    return out.stat().st_size


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        name, path = arg.split("=", 1)
        size = shoot(Path(path), IMG / f"{name}.png")
        sys.stdout.write(f"{name}.png: {size / 1e3:.0f} kB\n")
