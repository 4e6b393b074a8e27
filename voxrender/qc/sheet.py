"""Sheets: pictures laid out in a grid with captions, to compare views, methods or studies at a glance."""

from __future__ import annotations

import numpy as np


def sheet(rows, captions=None, gap=4, caption_height=16, background=(0, 0, 0), colour=(230, 230, 230)):
    """One RGB picture of ``rows`` of RGB pictures (each row a list), with a caption under each picture.

    Pictures of different sizes are placed at the top left of equal cells.

    >>> picture = np.full((8, 10, 3), 200, np.uint8)
    >>> sheet([[picture, picture]], [["a", "b"]], caption_height=0).shape
    (16, 32, 3)
    """
    from PIL import Image, ImageDraw

    height = max(p.shape[0] for row in rows for p in row)
    width = max(p.shape[1] for row in rows for p in row)
    cell_h, cell_w = height + caption_height + gap, width + gap
    columns = max(len(row) for row in rows)
    out = np.empty((len(rows) * cell_h + gap, columns * cell_w + gap, 3), np.uint8)
    out[:] = background
    for r, row in enumerate(rows):
        for c, picture in enumerate(row):
            top, left = gap + r * cell_h, gap + c * cell_w
            picture = np.asarray(picture)
            out[top:top + picture.shape[0], left:left + picture.shape[1]] = (
                picture if picture.ndim == 3 else picture[..., None])[..., :3]
    if captions and caption_height:
        image = Image.fromarray(out)
        draw = ImageDraw.Draw(image)
        for r, row in enumerate(captions):
            for c, text in enumerate(row):
                draw.text((gap + c * cell_w + 2, gap + r * cell_h + height + 2), str(text), fill=tuple(colour))
        out = np.asarray(image)
    return out


def render_sheet(rows, views, progress=None):
    """A sheet of pictures: one row per ``(label, encoded, options)``, one column per ``(label, (alpha, beta,
    gamma))`` view; captions "row label, view label".  ``encoded`` is a :class:`~voxrender.object.pipeline.Encoded`.

    A row of several views frames them with one scale, as a batch does.
    """
    from .._render import octree_for
    from ..pictures import picture

    pictures, captions = [], []
    for row_label, encoded, options in rows:
        tree = octree_for(options.method, encoded)
        pictures.append([picture(encoded.segments, v, options, progress, tree).rgb
                         for v in framed_views(encoded.segments, options, views)])
        captions.append([f"{row_label}, {label}" for label, _ in views])
    return sheet(pictures, captions)



def framed_views(segments, options, views):
    """The :class:`~voxrender.space.view.View` of each ``(label, (alpha, beta, gamma))`` of ``views`` as a row of a
    sheet frames them: without a scale, one that fits the object in every view, each centred (as a batch frames its
    views), so that the row does not change size from picture to picture.
    """
    from .._render import framing_box
    from ..space.view import frame_together

    chosen = [options.view(*angles) for _, angles in views]
    if options.scale is None and options.fit == "object":
        chosen = frame_together(chosen, segments.shape, framing_box(segments, options.clip))
    return chosen
