"""Rewrite the golden images: ``make golden`` (look at them before committing)."""

import tempfile
from pathlib import Path

from voxrender import io, samples

GOLDEN = Path(__file__).resolve().parent / "golden"

if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as folder:
        rgb, _ = samples.demo_picture(folder)
    io.write_png(GOLDEN / "demo.png", rgb)
    print(GOLDEN / "demo.png")
