import numpy as np
import pytest

from voxrender.pictures.marks import draw_marks, edge_letters
from voxrender.space.view import PRESETS, View

# The README's preset table, as the letters a radiologist would write at the left, right, top and bottom edges.
EXPECTED = {"anterior": "RLSI", "posterior": "LRSI", "left": "APSI", "right": "PASI", "superior": "LRAP",
            "inferior": "RLAP"}


@pytest.mark.parametrize("name", list(PRESETS))
def test_letters_of_each_preset(name):
    letters = edge_letters(View(*PRESETS[name]))
    assert "".join(letters[edge] for edge in ("left", "right", "top", "bottom")) == EXPECTED[name]


def test_oblique_views_name_two_directions():
    letters = edge_letters(View(90, 45, 0))          # between anterior and left
    assert set(letters["left"]) == {"R", "A"} and letters["top"] == "S"


def test_marks_are_drawn_at_the_edges():
    rgb = np.zeros((64, 64, 3), np.uint8)
    marked = draw_marks(rgb, View(*PRESETS["anterior"]))
    changed = marked.any(axis=2)
    assert changed[:, :10].any() and changed[:, -10:].any() and changed[:12].any() and changed[-14:].any()
    assert not changed[20:44, 20:44].any()
