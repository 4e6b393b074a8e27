"""Running a case: each command in a subprocess (the venv's voxrender) under a memory and a time limit, and its
outcome read from the exit status, the error stream, what it left in its output folder and what it did to its input.
"""

import hashlib
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from voxrender.object import vxs

from . import cases

VOXRENDER = Path(sys.executable).with_name("voxrender")
MEMORY_LIMIT = 2 * 1024**3          # RLIMIT_AS, bytes
TIME_LIMIT = 60                     # seconds per command
GOOD = ("picture", "bad input")
MISBEHAVIOURS = ("internal error", "signal", "timeout", "memory", "traceback", "partial output", "output escaped",
                 "input modified", "bad input message", "not generated")
NOTES = ("warning: ", "note: ")     # lines a command may print before its error line
KEPT = Path(__file__).resolve().parents[1] / "fuzz_cases"
PICTURE_COMMANDS = ("render", "slices", "sheet")    # each writes its picture to -o, and to --dicom-out if given


def _limits():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run_command(command, case, out):
    """Run one voxrender command line of a case; returns ``(outcome, stderr's last lines)``."""
    args = [str(VOXRENDER)] + [a.replace("{case}", str(case)).replace("{out}", str(out)) for a in command]
    env = {**os.environ, "COLUMNS": "120"}
    env.pop("VOXRENDER_DEBUG", None)
    try:
        done = subprocess.run(args, capture_output=True, text=True, errors="replace", timeout=TIME_LIMIT,
                              preexec_fn=_limits, env=env, cwd=case, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return "timeout", []
    lines = done.stderr.strip().splitlines()
    return classify(command, done.returncode, lines, out), lines[-3:]


def classify(command, status, lines, out):
    """The outcome of a ``command`` line from its exit ``status``, its stderr ``lines`` and its output folder
    ``out``: a picture command must write exactly its picture (``x.png``, and ``x.dcm`` when asked), each readable,
    and an encode exactly its ``x.vxs``, readable (its outcome is then called ``"picture"`` too)."""
    name = command[0]
    if status < 0:
        return "signal"
    if any(line.startswith("Traceback (most recent call last)") for line in lines):
        return "traceback"
    if status == 1:
        return "memory" if any("out of memory" in line or "MemoryError" in line for line in lines) else \
            "internal error"
    messages = [line for line in lines if not line.startswith(NOTES)]
    if name == "batch":
        return _batch_outcome(status, messages, out / "batch")
    if status == 0:
        if name in PICTURE_COMMANDS:
            return "picture" if _only_picture(out, dicom="--dicom-out" in command) else "partial output"
        if name == "encode":
            return "picture" if _only_segments(out) else "partial output"
        return "picture"
    # an encode leaves nothing on bad input, not even the empty folder of its streamed parts
    left = list(out.rglob("*")) if name == "encode" else _files(out)
    if status == 2 and len(messages) == 1 and messages[0].startswith("error: "):
        return "bad input" if not left else "partial output"
    return "internal error" if status != 2 else "partial output" if left else "bad input message"


def _batch_outcome(status, messages, folder):
    """A batch ends in pictures (exit 0, every row's picture on disk and readable), or in exit 2 with one error line
    or one ``failed:`` line per failed input, whose rows the summary marks failed."""
    if status == 0:
        return "picture" if _summary_agrees(folder) else "partial output"
    if status != 2:
        return "internal error"
    if any("internal error" in line for line in messages):
        return "internal error"
    if len(messages) == 1 and messages[0].startswith("error: "):
        return "bad input"
    if messages and all(line.startswith("failed: ") for line in messages):
        return "bad input" if _summary_agrees(folder) else "partial output"
    return "bad input message"


def _summary_agrees(folder):
    """Whether every ``ok`` row of the batch's summary names a picture that reads, and no failed row left one."""
    import csv

    summary = folder / "summary.csv"
    if not summary.exists():
        return not folder.exists() or not any(p.suffix == ".png" for p in folder.rglob("*"))
    with open(summary, newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        picture = folder / row["output"] if row.get("output") else None
        if row["status"] in ("ok", "done earlier") and not (picture and _reads(picture)):
            return False
    return True


def _files(folder):
    return [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []


def _only_picture(out, dicom=False):
    """Whether ``out`` holds ``x.png`` (and ``x.dcm`` if ``dicom``), nothing else, and each reads."""
    files = sorted(_files(out))
    expected = [out / "x.dcm", out / "x.png"] if dicom else [out / "x.png"]
    return files == expected and _reads(out / "x.png") and (not dicom or _reads_dicom(out / "x.dcm"))


def _only_segments(out):
    """Whether ``out`` holds ``x.vxs``, nothing else (no parts of a streamed encode left behind), and
    :func:`voxrender.object.vxs.load` reads it."""
    if sorted(out.rglob("*")) != [out / "x.vxs"]:
        return False
    try:
        vxs.load(out / "x.vxs")
        return True
    except Exception:  # noqa: BLE001 - any failure to read the file is what this looks for
        return False


def _reads(picture):
    try:
        from PIL import Image

        with Image.open(picture) as image:
            image.load()
        return True
    except Exception:  # noqa: BLE001 - any failure to read the picture is what this looks for
        return False


def _reads_dicom(path):
    """Whether pydicom reads ``path`` as an RGB picture: its header and its pixel data, of the size it says."""
    try:
        import pydicom

        ds = pydicom.dcmread(path)
        pixels = ds.pixel_array
        return pixels.shape == (ds.Rows, ds.Columns, 3) and ds.SamplesPerPixel == 3
    except Exception:  # noqa: BLE001 - any failure to read the file is what this looks for
        return False


def _hashes(folder):
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def run_in(case, commands):
    """Run a case's commands in its folder ``case``; returns ``(outcome, stderr's last lines, command)`` of the
    first command that misbehaved, or of the last one."""
    inputs = case / cases.seeds.INPUT
    before = _hashes(inputs)
    outcome, tail, command = "picture", [], None
    for command in commands:
        out = case / "out"
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir()
        outcome, tail = run_command(command, case, out)
        if outcome not in GOOD:
            break
        escaped = sorted(str(p.relative_to(case)) for p in case.rglob("*")
                         if p.is_file() and not p.is_relative_to(out) and not p.is_relative_to(inputs))
        if escaped:
            outcome, tail = "output escaped", escaped[:3]
            break
        if _hashes(inputs) != before:
            outcome, tail = "input modified", []
            break
    return outcome, tail, command


def slug(name):
    """A folder name for a case name: its words, with what a path cannot hold replaced."""
    keep = "".join(c if c.isalnum() or c in "-_.=[]" else "_" for c in name.replace("/", "__"))
    return keep[:120]


def run_case(seed, number, keep=KEPT):
    """Make and run case ``number`` of ``seed`` in a scratch folder; keep it under ``keep`` if it misbehaved.
    Returns ``(number, name, format, outcome, tail)``."""
    with tempfile.TemporaryDirectory(prefix="fuzz-") as scratch:
        case = Path(scratch)
        try:
            made = cases.make_case(seed, number, case)
        except Exception as exc:  # noqa: BLE001 - a seed the generator cannot write is the gate's own bug
            return number, f"?/{seed}/{number}", "?", "not generated", [f"{type(exc).__name__}: {exc}"]
        outcome, tail, command = run_in(case, made.commands)
        if outcome not in GOOD and keep is not None:
            kept = keep / outcome.replace(" ", "-") / slug(f"{seed}-{number}-{made.name}")
            shutil.rmtree(kept, ignore_errors=True)
            kept.mkdir(parents=True)
            cases.copy_input(case, kept)
            (kept / "case.json").write_text(json.dumps(
                {"name": made.name, "seed": seed, "number": number, "format": made.format, "outcome": outcome,
                 "commands": made.commands, "failed command": command, "stderr": tail}, indent=1) + "\n")
        return number, made.name, made.format, outcome, tail


def run_seed(name):
    """Write the valid seed file of format ``name``, undamaged, and run its render (or batch), then its streamed
    encode (but of a batch or an encoded input); its outcome."""
    with tempfile.TemporaryDirectory(prefix="fuzz-seed-") as scratch:
        case = Path(scratch)
        (case / cases.seeds.INPUT).mkdir()
        values, spacing, direction = cases.seeds.phantom_stored()
        seed = cases.FORMATS[name].write(case, values, spacing, direction)
        commands = cases.commands_for(_NoExtras(), seed)
        if seed.command != "batch" and not seed.path.endswith((".vxs", ".vxo")):
            commands.append(cases.encode_command(_NoExtras(), seed, cases.case_options(seed)))
        return run_in(case, commands)


class _NoExtras:
    """A stand-in for the case's random choices that adds no threshold, no ``info`` and no other command, and
    takes the first of any choice."""

    def random(self):
        return 1.0

    def choice(self, items):
        return items[0]


def replay(kept):
    """Run a kept case (a folder with its ``case.json`` and ``input/``) again, in a scratch copy; its outcome."""
    record = json.loads((kept / "case.json").read_text())
    with tempfile.TemporaryDirectory(prefix="fuzz-replay-") as scratch:
        case = Path(scratch)
        cases.copy_input(kept, case)
        return run_in(case, record["commands"])
