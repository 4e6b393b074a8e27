"""The golden pictures: what each case renders to, and ``make golden`` to rewrite them after an intended change.

Look at every picture before committing new ones.  A case is the command line of ``voxrender`` that makes it;
``{samples}`` is a folder of the built-in samples and ``{data}`` the real data in ``../shared/data``.
"""

import sys
import tempfile
from pathlib import Path

from click.testing import CliRunner

from voxrender.cli import main
from voxrender.render import METHODS

GOLDEN = Path(__file__).resolve().parent / "golden"
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SHELL = ["render", "{samples}/shell", "--threshold", "500", "--alpha", "100", "--beta", "20", "--size", "96"]
CASES = {
    "demo": ["demo", "--headsq", str(Path(__file__).resolve().parents[1] / "samples" / "headsq"), "--size", "96"],
    **{f"shell-{method}": SHELL + ["--method", method] for method in sorted(METHODS)},
    "shell-gamma": SHELL + ["--gamma", "30"],
    "shell-cutaway": SHELL + ["--cut-depth", "0", "--light", "1,-1,-2"],
    "headsq-bone": ["render", "{data}/headsq", "--raw", "64x64:uint16:little", "--spacing", "3.2,3.2,1.5",
                    "--threshold", "1150", "--view", "anterior", "--size", "128"],
}
REAL_DATA = {"headsq-bone"}


def render_case(name, output, samples, data=DATA):
    """Run the case's command, writing its picture to ``output``."""
    args = [a.format(samples=samples, data=data) for a in CASES[name]] + ["-o", str(output)]
    if name != "demo" and not (Path(samples) / "shell").is_dir():
        CliRunner().invoke(main, ["samples", str(samples)])
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, (args, result.output)


if __name__ == "__main__":
    names = sys.argv[1:] or list(CASES)
    with tempfile.TemporaryDirectory() as folder:
        for name in names:
            render_case(name, GOLDEN / f"{name}.png", Path(folder) / "samples")
            print(GOLDEN / f"{name}.png")
