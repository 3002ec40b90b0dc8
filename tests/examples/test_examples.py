"""The generated large panel: face count, extent, crown height and normals."""

import numpy as np
import pytest

from swath.errors import InputError
from swath.examples import large_panel


@pytest.mark.parametrize("n_faces", [20_000, 80_000])
def test_large_panel_has_the_asked_size(n_faces):
    s = large_panel(n_faces=n_faces)
    assert abs(len(s.faces) - n_faces) <= 0.01 * n_faces
    np.testing.assert_allclose(s.vertices[:, :2].max(0) - s.vertices[:, :2].min(0), [1.2, 0.8])
    # Crown at the centre: both arcs are zero there, the swell is 10 mm; corners drop by both sagittas.
    centre = np.argmin(np.linalg.norm(s.vertices[:, :2], axis=1))
    assert s.vertices[centre, 2] == pytest.approx(0.01, abs=1e-4)
    sag = (np.sqrt(1.5**2 - 0.6**2) - 1.5) + (np.sqrt(4.0**2 - 0.4**2) - 4.0)
    assert s.vertices[:, 2].min() == pytest.approx(sag, rel=1e-9)
    assert (s.vertex_normals[:, 2] > 0.9).all()


def test_large_panel_refuses_radii_below_half_the_extent():
    with pytest.raises(InputError, match="radius_x"):
        large_panel(n_faces=1000, radius_x=0.5)
