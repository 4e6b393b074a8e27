"""Marks on a picture: the patient direction at each edge, as radiologists label them, and a legend of labels.

Directions come from the canonical patient frame (x toward the patient's left, y toward the back, z toward the
head), so they are right for every input whose orientation is known.
"""

from __future__ import annotations

import numpy as np

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

    >>> from voxrender.space.view import View, PRESETS
    >>> edge_letters(View(*PRESETS["anterior"]))
    {'left': 'R', 'right': 'L', 'top': 'S', 'bottom': 'I'}
    """
    r = view.matrix                 # row i: image axis i in object coordinates
    return {"left": _letter(-r[0]), "right": _letter(r[0]), "top": _letter(-r[1]), "bottom": _letter(r[1])}


def draw_marks(rgb, view, colour=(255, 220, 0)):
    """``rgb`` with the edge letters of ``view`` (:func:`edge_letters`) written at the middle of each edge."""
    return draw_letters(rgb, edge_letters(view), colour)


def draw_letters(rgb, letters, colour=(255, 220, 0)):
    """``rgb`` with ``letters`` (``{"left", "right", "top", "bottom"} -> text``) at the middle of each edge.

    >>> picture = draw_letters(np.zeros((40, 40, 3), np.uint8), {"left": "R"})
    >>> bool(picture[:, :10].any()), bool(picture[:, 10:].any())
    (True, False)
    """
    from PIL import Image, ImageDraw

    image = Image.fromarray(np.ascontiguousarray(rgb))
    draw = ImageDraw.Draw(image)
    height, width = rgb.shape[:2]
    places = {"left": lambda text: (3, height // 2 - 5),
              "right": lambda text: (width - 3 - 6 * len(text), height // 2 - 5),
              "top": lambda text: (width // 2 - 3 * len(text), 2),
              "bottom": lambda text: (width // 2 - 3 * len(text), height - 13)}
    for edge, text in letters.items():
        draw.text(places[edge](text), str(text), fill=tuple(colour))
    return np.asarray(image)


def draw_legend(rgb, entries, text=(235, 235, 235)):
    """``rgb`` with a legend in its lower left corner: a swatch and a name for each ``(name, (r, g, b))`` of
    ``entries``, on a dark band; what does not fit is summed up as "+N more".

    >>> picture = draw_legend(np.zeros((60, 80, 3), np.uint8), [("bone", (241, 214, 145))])
    >>> picture.shape, bool((picture == (241, 214, 145)).all(axis=2).any())
    ((60, 80, 3), True)
    """
    from PIL import Image, ImageDraw

    image = Image.fromarray(np.ascontiguousarray(rgb))
    draw = ImageDraw.Draw(image)
    height, width = rgb.shape[:2]
    line = 12                                                   # the default bitmap font is 11 pixels high
    room = max((height - 8) // line, 1)
    shown = list(entries) if len(entries) <= room else list(entries)[:room - 1]
    lines = [(name, colour) for name, colour in shown]
    if len(shown) < len(entries):
        lines.append((f"+{len(entries) - len(shown)} more", None))
    widest = max((draw.textlength(name) for name, _ in lines), default=0)
    top = height - 4 - line * len(lines)
    band = np.asarray(image).copy()
    band[max(top - 3, 0):, :min(int(widest) + 24, width)] //= 3            # darken, so the names can be read
    image = Image.fromarray(band)
    draw = ImageDraw.Draw(image)
    for k, (name, colour) in enumerate(lines):
        y = top + k * line
        if colour is not None:
            draw.rectangle((4, y + 1, 12, y + 9), fill=tuple(int(c) for c in colour))
        draw.text((17, y), name, fill=text)
    return np.asarray(image)
