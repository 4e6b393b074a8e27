"""voxrender installed afresh, outside the checkout: the wheel check, and the renewal of ``constraints.txt``.

``python tests/fresh_install.py`` (``make wheel-check``, run by CI) builds the sdist and from it the wheel, installs
the wheel with ``constraints.txt`` into a new venv in a temporary folder, and in an empty folder there imports
voxrender and runs ``voxrender demo``: the package works wherever it is installed, its quarter head included.  It
takes a minute or two (the dependencies install from pip's cache), so it is not part of ``make test``.

``python tests/fresh_install.py --constraints`` (``make constraints``) installs ``.[test,lint,docs]`` into a new
venv without constraints and writes what it got into ``constraints.txt``: the newest versions that install today.

Both print each command they run.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONSTRAINTS = ROOT / "constraints.txt"
EXTRAS = "test,lint,docs"
# pip's own version is pinned with the rest; setuptools is the build's (pyproject.toml's build-system)
UNPINNED = ("voxrender", "setuptools")
HEADER = """\
# The versions CI last passed with. `make test`, `make wheel-check` and CI install with `-c constraints.txt`.
# Renew it with `make constraints` (a fresh venv installs .[{extras}] without constraints: this is its pip
# freeze), then run `make test` and `make wheel-check` before committing it. Written on Python {python}, {system}.
"""
# the commands see neither the checkout nor the venv they were started from
ENVIRONMENT = {name: value for name, value in os.environ.items() if name not in ("PYTHONPATH", "VIRTUAL_ENV")}


def run(*command, cwd=None, capture=False):
    """Run ``command``, printed first; a failure ends the script with the command's status."""
    command = [str(part) for part in command]
    print("+", " ".join(command), flush=True)
    done = subprocess.run(command, cwd=cwd, env=ENVIRONMENT, capture_output=capture, text=True)
    if done.returncode:
        sys.exit(f"failed ({done.returncode}): {' '.join(command)}\n{done.stdout or ''}{done.stderr or ''}")
    return done.stdout


def fresh_venv(folder, constraints=None):
    """A new venv in ``folder`` with pip upgraded (to the version ``constraints`` pins, when given); its bin folder."""
    run(sys.executable, "-m", "venv", folder)
    bin_folder = Path(folder) / "bin"
    run(bin_folder / "python", "-m", "pip", "install", "--quiet", "--upgrade", "pip",
        *(["-c", constraints] if constraints else []))
    return bin_folder


def wheel_check():
    """Build the wheel, install it outside the checkout and render the demo in an empty folder."""
    with tempfile.TemporaryDirectory(prefix="voxrender-wheel-") as scratch:
        scratch = Path(scratch)
        run(sys.executable, "-m", "build", "--quiet", "--outdir", scratch / "dist", ROOT)
        (wheel,) = (scratch / "dist").glob("*.whl")
        bin_folder = fresh_venv(scratch / "venv", CONSTRAINTS)
        run(bin_folder / "python", "-m", "pip", "install", "--quiet", wheel, "-c", CONSTRAINTS)
        elsewhere = scratch / "elsewhere"
        elsewhere.mkdir()
        installed = run(bin_folder / "python", "-c", "import sys, voxrender; print(voxrender.__version__); "
                        "assert voxrender.__file__.startswith(sys.prefix), voxrender.__file__",
                        cwd=elsewhere, capture=True).strip()
        if not wheel.name.startswith(f"voxrender-{installed}-"):
            sys.exit(f"the wheel {wheel.name} installed voxrender {installed}")
        run(bin_folder / "voxrender", "demo", "-o", "demo.png", cwd=elsewhere)
        demo = elsewhere / "demo.png"
        if not demo.is_file() or demo.stat().st_size == 0:
            sys.exit(f"voxrender demo wrote no picture to {demo}")
        # a batch's index page: its style and script are package data the wheel must carry
        run(bin_folder / "voxrender", "samples", "samples", "--name", "sphere", cwd=elsewhere)
        run(bin_folder / "voxrender", "batch", "samples/sphere.nii.gz", "--threshold", "500", "--size", "32", "-o",
            "batch", cwd=elsewhere)
        page = (elsewhere / "batch" / "index.html").read_text()
        if "function thumbnail(" not in page or ".flag.bad{" not in page:
            sys.exit("the index page of the installed package lacks its script or its style")
        print(f"{wheel.name}: installed outside the checkout, voxrender {installed} imports, `voxrender demo` "
              f"wrote {demo.stat().st_size} bytes, and a batch's index page has its script and style")


def renew_constraints():
    """Write ``constraints.txt`` from a fresh venv that installed ``.[test,lint,docs]`` without constraints."""
    with tempfile.TemporaryDirectory(prefix="voxrender-constraints-") as scratch:
        bin_folder = fresh_venv(Path(scratch) / "venv")
        run(bin_folder / "python", "-m", "pip", "install", "--quiet", "-e", f"{ROOT}[{EXTRAS}]")
        frozen = run(bin_folder / "python", "-m", "pip", "freeze", "--all",
                     *(f"--exclude={name}" for name in UNPINNED), capture=True)
    header = HEADER.format(extras=EXTRAS, python=platform.python_version(), system=f"{platform.system()} "
                           f"{platform.machine()}")
    CONSTRAINTS.write_text(header + frozen)
    print(f"{CONSTRAINTS}: {len(frozen.splitlines())} distributions pinned")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--constraints", action="store_true", help="renew constraints.txt instead")
    started = time.perf_counter()
    if parser.parse_args().constraints:
        renew_constraints()
    else:
        wheel_check()
    print(f"done in {time.perf_counter() - started:.0f} s")
