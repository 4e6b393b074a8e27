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


# A legend may cover at most this share of a picture; a longer one goes beside it, in columns.
LEGEND_SHARE = 1 / 6
LINE = 12                           # pixels a legend line takes: the default bitmap font is 11 pixels high
PANEL_WIDTHS = 4                    # a legend beside the picture is at most this many times the picture's width


def draw_legend(rgb, entries, text=(235, 235, 235)):
    """``rgb`` with a legend of its labels: a swatch and a name for each ``(name, (r, g, b))`` of ``entries``.

    A short legend is drawn in the lower left corner on a dark band.  One that would cover more than
    ``LEGEND_SHARE`` of the picture (30 organs of TotalSegmentator on a thumbnail) goes beside it instead, on a
    panel as high as the picture, in as many columns as it needs (the picture grows wider); what does not fit even
    there is summed up as "+N more".

    >>> picture = draw_legend(np.zeros((60, 80, 3), np.uint8), [("bone", (241, 214, 145))])
    >>> picture.shape, bool((picture == (241, 214, 145)).all(axis=2).any())
    ((60, 80, 3), True)
    >>> wide = draw_legend(np.zeros((60, 80, 3), np.uint8), [(f"organ {k}", (255, 0, 0)) for k in range(9)])
    >>> wide.shape[0], wide.shape[1] > 80, bool(wide[:, :80].any())          # beside the picture, not over it
    (60, True, False)
    """
    from PIL import Image, ImageDraw

    height, width = rgb.shape[:2]
    measure = ImageDraw.Draw(Image.new("RGB", (1, 1))).textlength
    room = max((height - 8) // LINE, 1)
    lines = _fitted([(str(name), colour) for name, colour in entries], room)
    corner = (max((measure(name) for name, _ in lines), default=0) + 24) * (LINE * len(lines) + 7)
    if corner <= LEGEND_SHARE * height * width or len(entries) <= 1:
        return _corner_legend(rgb, lines, measure, text)
    entries = [(str(name), colour) for name, colour in entries]
    columns = [entries[k:k + room] for k in range(0, len(entries), room)]
    while len(columns) > 1 and sum(_column_width(c, measure) for c in columns) > PANEL_WIDTHS * width:
        columns.pop()
    shown = sum(len(c) for c in columns)
    if shown < len(entries):
        columns[-1] = columns[-1][:-1] + [(f"+{len(entries) - shown + 1} more", None)]
    panel = np.zeros((height, sum(_column_width(c, measure) for c in columns) + 4, 3), np.uint8)
    panel[:] = np.asarray(rgb).reshape(-1, 3).min(axis=0) // 3 if rgb.size else 0
    image = Image.fromarray(np.ascontiguousarray(np.concatenate([rgb, panel], axis=1)))
    draw, left = ImageDraw.Draw(image), width
    for column in columns:
        _write(draw, column, left, 4, text)
        left += _column_width(column, measure)
    return np.asarray(image)


def _fitted(lines, room):
    """``lines`` cut to ``room``, the last one then saying how many more there are."""
    if len(lines) <= room:
        return lines
    shown = lines[:max(room - 1, 0)]
    return shown + [(f"+{len(lines) - len(shown)} more", None)]


def _column_width(column, measure):
    return int(max(measure(name) for name, _ in column)) + 28


def _corner_legend(rgb, lines, measure, text):
    """The legend in the lower left corner of ``rgb``, on a band darkened so the names can be read."""
    from PIL import Image, ImageDraw

    height, width = rgb.shape[:2]
    widest = max((measure(name) for name, _ in lines), default=0)
    top = height - 4 - LINE * len(lines)
    band = np.array(rgb, copy=True)
    band[max(top - 3, 0):, :min(int(widest) + 24, width)] //= 3
    image = Image.fromarray(np.ascontiguousarray(band))
    _write(ImageDraw.Draw(image), lines, 0, top, text)
    return np.asarray(image)


def _write(draw, lines, left, top, text):
    """A swatch and a name a line, from (``left``, ``top``)."""
    for k, (name, colour) in enumerate(lines):
        y = top + k * LINE
        if colour is not None:
            draw.rectangle((left + 4, y + 1, left + 12, y + 9), fill=tuple(int(c) for c in colour))
        draw.text((left + 17, y), name, fill=text)
