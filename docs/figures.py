"""Draw the Concepts pages' figures from swath's own functions: ``python docs/figures.py``.

Writes ``docs/img/concept-*.png``: the contact patch and swath width against curvature
(:func:`swath.contact.model.local_patch`), the cross-profile of one pass
(:func:`swath.feed.ripple.cross_profile`) and the ripple of parallel passes against their spacing
(:func:`swath.feed.ripple.ripple_cov`), pressed flat and led at the half-pad angle.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from swath.contact import Tool  # noqa: E402
from swath.contact.model import local_patch  # noqa: E402
from swath.feed.ripple import cross_profile, ripple_cov  # noqa: E402

IMG = Path(__file__).resolve().parent / "img"


def contact_figure(tool: Tool, path: Path) -> None:
    """Contact patch outlines on a flat, a convex cylinder and a convex sphere; widest swath
    against curvature."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    R = tool.pad_radius
    for (k1, k2), label in (((0.0, 0.0), "flat"), ((10.0, 0.0), "cylinder, radius 100 mm"),
                            ((20.0, 20.0), "sphere, radius 50 mm")):
        patch = local_patch([k1], [k2], tool)
        phi = np.append(patch.phi, patch.phi[0])
        rho = np.append(patch.rho_out[0], patch.rho_out[0, 0])
        a.plot(1e3 * rho * np.cos(phi), 1e3 * rho * np.sin(phi), label=label)
    t = np.linspace(0, 2 * np.pi, 200)
    a.plot(1e3 * R * np.cos(t), 1e3 * R * np.sin(t), "k:", lw=0.8, label="pad rim")
    a.set_aspect("equal")
    a.set_xlabel("x, mm (along the feed)")
    a.set_ylabel("y, mm")
    a.set_title(f"contact patch at {tool.force:g} N")
    a.legend(fontsize=8, loc="lower right")
    kappa = np.linspace(0.0, 60.0, 61)
    widths = local_patch(kappa, np.zeros_like(kappa), tool).width_across(0.0)
    b.plot(kappa, 1e3 * widths, label="swath width across the curvature (swath)")
    s = local_patch(kappa[1:], np.zeros_like(kappa[1:]), tool).sink
    b.plot(kappa[1:], 1e3 * np.minimum(2 * np.sqrt(2 * s / kappa[1:]), 2 * R), "--",
           label=r"$2\sqrt{2s/\kappa}$ (chord of the sunk pad)")
    b.set_xlabel("curvature κ, 1/m (cylinder)")
    b.set_ylabel("width, mm")
    b.set_title("swath width against curvature")
    b.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def ripple_figure(tool: Tool, path: Path) -> None:
    """One pass's removal cross-profile; summed profiles' CoV against spacing, flat and led."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    R = tool.pad_radius
    y = np.linspace(-R, R, 301)
    lead = tool.half_pad_lead
    for angle, label in ((0.0, "pad pressed flat"), (lead, f"led {np.degrees(lead):.1f}°")):
        prof = cross_profile(tool, y, speed=0.05, lead_angle=angle)
        a.plot(1e3 * y, prof / prof.max(), label=label)
    a.set_xlabel("offset across the pass, mm")
    a.set_ylabel("removal / its maximum")
    a.set_title("removal across one pass")
    a.legend(fontsize=8)
    d = np.linspace(0.6 * R, 2.0 * R, 120)
    for angle, label in ((0.0, "pad pressed flat"), (lead, f"led {np.degrees(lead):.1f}°")):
        cov = [ripple_cov(tool, float(x), lead_angle=angle) for x in d]
        b.plot(d / R, 100 * np.asarray(cov), label=label)
    b.axvline(2 / 1.5, color="k", ls=":", lw=0.8)
    b.text(2 / 1.5, b.get_ylim()[1] * 0.9, " path = 1.5 L*", fontsize=8)
    b.set_xlabel("pass spacing d / R")
    b.set_ylabel("ripple CoV, %")
    b.set_title("ripple of parallel passes")
    b.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    IMG.mkdir(exist_ok=True)
    tool = Tool()
    contact_figure(tool, IMG / "concept-contact.png")
    ripple_figure(tool, IMG / "concept-ripple.png")


if __name__ == "__main__":
    main()
