"""The docs' notebook runs from top to bottom, and its pictures show themselves (a PNG in each picture's output)."""

import base64
import io
from pathlib import Path

import numpy as np
import pytest

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "notebook.ipynb"


def test_the_notebook_runs_and_shows_its_pictures():
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    from PIL import Image

    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(notebook, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": str(NOTEBOOK.parent)}}).execute()
    shown = [output["data"]["image/png"] for cell in notebook.cells if cell.cell_type == "code"
             for output in cell.outputs if "image/png" in output.get("data", {})]
    assert len(shown) == 3                              # the surface, the projection, the slices
    pictures = [np.asarray(Image.open(io.BytesIO(base64.b64decode(png)))) for png in shown]
    assert [p.shape[:2] for p in pictures[:2]] == [(256, 256), (256, 256)]
    assert all(p.any() for p in pictures)


def test_a_picture_shows_itself_as_png():
    from PIL import Image

    import voxrender

    zz, yy, xx = np.mgrid[:12, :12, :12]
    ball = (xx - 5.5) ** 2 + (yy - 5.5) ** 2 + (zz - 5.5) ** 2 <= 16
    from voxrender.object.segments import encode

    result = voxrender.picture(encode(ball),
                               voxrender.View(30, 20, size=(24, 24)))
    decoded = np.asarray(Image.open(io.BytesIO(result._repr_png_())))
    np.testing.assert_array_equal(decoded, result.rgb)
