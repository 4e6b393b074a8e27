"""voxrender: shaded pictures of the object inside a stack of CT-like slices.

The pipeline, one module per step::

    io.read_volume ─► prep.binarize ─► segments.encode ─► render.render ─► shade.shade
        ─► output.write_png

``picture.picture`` is the render and shade step of every command; ``docs/design.md`` has the whole design.

>>> import numpy as np
>>> from voxrender import segments, view, render, shade
>>> zz, yy, xx = np.mgrid[:16, :16, :16]
>>> mask = (xx - 7.5) ** 2 + (yy - 7.5) ** 2 + (zz - 7.5) ** 2 <= 36
>>> image = render.render(segments.encode(mask), view.View(size=(32, 32), scale=1.5), method="btf")
>>> rgb = shade.shade(image.depth)
>>> rgb.shape
(32, 32, 3)
"""

__version__ = "0.1.0"
