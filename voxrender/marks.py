"""Orientation marks: the patient direction at each edge of a picture, as radiologists label them.

Directions come from the canonical patient frame (x toward the patient's left, y toward the back, z toward the
head), so they are right for every input whose orientation is known.
"""

from __future__ import annotations

import numpy as np

__all__ = ["edge_letters", "draw_marks"]

_TOWARD = ("L", "P", "S")     # the side each object axis grows toward
_AWAY = ("R", "A", "I")


def _letter(direction):
    """The patient side nearest an object-space direction: one letter, or two when a second axis is close."""
    order = np.argsort(-np.abs(direction))
    letters = ""
    for k in order[:2]:
        if abs(direction[k]) >= 0.38 or not letters:          # within about 67 degrees: name it too
            letters += (_TOWARD if direction[k] > 0 else _AWAY)[k]
    return letters


def edge_letters(view):
    """``{"left", "right", "top", "bottom"}`` -> the patient direction at that edge of ``view``'s picture.

    >>> from voxrender.view import View, PRESETS
    >>> edge_letters(View(*PRESETS["anterior"]))
    {'left': 'R', 'right': 'L', 'top': 'S', 'bottom': 'I'}
    """
    r = view.matrix                 # row i: image axis i in object coordinates
    return {"left": _letter(-r[0]), "right": _letter(r[0]), "top": _letter(-r[1]), "bottom": _letter(r[1])}


def draw_marks(rgb, view, colour=(255, 220, 0)):
    """``rgb`` with the edge letters written at the middle of each edge."""
    from PIL import Image, ImageDraw

    image = Image.fromarray(np.ascontiguousarray(rgb))
    draw = ImageDraw.Draw(image)
    height, width = rgb.shape[:2]
    letters = edge_letters(view)
    places = {"left": (3, height // 2 - 5), "right": (width - 3 - 6 * len(letters["right"]), height // 2 - 5),
              "top": (width // 2 - 3 * len(letters["top"]), 2), "bottom": (width // 2 - 3 * len(letters["bottom"]),
                                                                          height - 13)}
    for edge, (x, y) in places.items():
        draw.text((x, y), letters[edge], fill=tuple(colour))
    return np.asarray(image)
