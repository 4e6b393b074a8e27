"""Rewrite the golden images: ``make golden`` (look at them before committing)."""

import tempfile
from pathlib import Path

from click.testing import CliRunner

from voxrender.cli import main

GOLDEN = Path(__file__).resolve().parent / "golden"

if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as folder:
        result = CliRunner().invoke(main, ["demo", "-o", str(GOLDEN / "demo.png"), "--samples-folder", folder])
        assert result.exit_code == 0, result.output
    print(GOLDEN / "demo.png")
