"""The library speaks Python: its errors name the parameter at fault, never a command-line flag.

Only ``voxrender/cli/`` and ``voxrender/batch/parse.py`` deal with flags; the CLI turns an error's ``parameter``
into its flag when it reports it (``cli.flag``).
"""

import ast
import re
from pathlib import Path

import voxrender
from voxrender.outputs.output_kinds import OUTPUTS

PACKAGE = Path(voxrender.__file__).parent
SPEAK_FLAGS = {*(PACKAGE / "cli").rglob("*.py"), PACKAGE / "batch" / "parse.py"}
ERRORS = {"InputError", "ValueError", "TypeError"}
FLAG = re.compile(r"--[A-Za-z]")


def flags_in_errors(source):
    """``(line, text)`` of every string literal (f-string parts too) given to an error that names a flag."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) in ERRORS:
            found += [(node.lineno, text.value) for text in ast.walk(node)
                      if isinstance(text, ast.Constant) and isinstance(text.value, str) and FLAG.search(text.value)]
    return found


def test_the_scan_finds_a_flag_in_an_error():
    source = ('def f(x):\n    raise InputError(f"{x} is too large; choose a smaller --voxel", parameter="voxel")\n'
              'def g():\n    raise ValueError("give " + "--threshold")\n'
              'def h():\n    raise errors.InputError("a size", parameter="size")\n')
    assert [line for line, _ in flags_in_errors(source)] == [2, 4]


def test_no_library_error_names_a_flag():
    modules = sorted(set(PACKAGE.rglob("*.py")) - SPEAK_FLAGS)
    assert len(modules) > 20
    found = [f"{path.relative_to(PACKAGE)}:{line}: {text!r}" for path in modules
             for line, text in flags_in_errors(path.read_text())]
    assert not found, "a library error names a flag; name the parameter= and say what is wrong in words:\n" + \
        "\n".join(found)


def test_no_output_need_names_a_flag():
    """What an output needs is refused by words kept in its record, not in a raise."""
    needs = [kind.needs for kind in OUTPUTS.values() if kind.needs is not None]
    assert needs and not [need.lacking for need in needs if FLAG.search(need.lacking)]
