"""The house's structure, from the code's own imports (``import`` statements anywhere, those inside functions
included): no import circle among voxrender's modules, no private name of one module taken by another, and no
private module of a package taken from outside it.  The literal oracles (``_render/literal/``) may take the fast
renderers' private names: they are those renderers' paper-shaped twins.

A package's ``__init__`` stands for the package: ``from voxrender.io import read_volume`` is an arrow to it.
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "voxrender"
ORACLES = "voxrender._render.literal"
# The layers of docs/design.md, bottom up: a module imports from its own layer and those below.  The package's own
# __init__ (its lazy face, which imports nothing until asked) stands above them all.
LAYERS = [("errors",), ("_shared",), ("space",), ("io", "samples"), ("object",), ("_render",), ("pictures",),
          ("outputs", "_snapshot"), ("qc",), ("review",), ("batch",), ("cli",)]


def modules_of(root):
    """``{dotted name: path}`` of the modules under ``root`` (a package folder), a package by its ``__init__``."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def imports_of(modules):
    """``{module: [(imported module, name or None, line)]}``: what each module imports, and each name it takes by
    ``from X import name`` when that name is not a module; and the names it uses as ``alias._name`` of a module it
    imported (``prep._blocks``), as ``(module, "_name", line)``."""
    top = next(iter(modules)).split(".")[0]
    found = {}
    for module, path in modules.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        taken, aliases = [], {}
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    base = ".".join(parts[:len(parts) - node.level + 1] + ([base] if base else []))
                if base.split(".")[0] != top:
                    continue
                for alias in node.names:
                    if f"{base}.{alias.name}" in modules:
                        taken.append((f"{base}.{alias.name}", None, node.lineno))
                        aliases[alias.asname or alias.name] = f"{base}.{alias.name}"
                    else:
                        taken.append((base, alias.name, node.lineno))
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split(".")[0] == top:
                        taken.append((alias.name, None, node.lineno))
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                    and _private(node.attr)):
                taken.append((aliases[node.value.id], node.attr, node.lineno))
        found[module] = taken
    return found


def _private(name):
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def circles(modules, imports):
    """The strongly connected groups of more than one module in the import graph (Tarjan's, iteratively)."""
    graph = {m: sorted({target for target, _, _ in imports[m] if target in modules and target != m}) for m in modules}
    order, low, on_stack, stack, groups = {}, {}, set(), [], []
    for start in graph:
        if start in order:
            continue
        work = [(start, iter(graph[start]))]
        order[start] = low[start] = len(order)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            for successor in successors:
                if successor not in order:
                    order[successor] = low[successor] = len(order)
                    stack.append(successor)
                    on_stack.add(successor)
                    work.append((successor, iter(graph[successor])))
                    break
                if successor in on_stack:
                    low[node] = min(low[node], order[successor])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == order[node]:
                    group = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.append(member)
                        if member == node:
                            break
                    if len(group) > 1:
                        groups.append(sorted(group))
    return groups


def private_names_taken(imports, oracles=ORACLES):
    """``module:line takes target.name`` for each private name one module takes from another."""
    return [f"{module}:{line} takes {target}.{name}" for module, taken in imports.items()
            if not module.startswith(oracles) for target, name, line in taken
            if name is not None and _private(name) and target != module]


def private_modules_taken(imports):
    """``module:line takes target`` for each private module (a part of its path private) taken from outside the
    package that holds it."""
    wrong = []
    for module, taken in imports.items():
        for target, _, line in taken:
            parts = target.split(".")
            for depth in range(1, len(parts)):
                if _private(parts[depth]):
                    owner = ".".join(parts[:depth])
                    if module != owner and not module.startswith(owner + "."):
                        wrong.append(f"{module}:{line} takes {target}")
                    break
    return wrong


def arrows_up(imports, layers=LAYERS):
    """``module:line takes target`` for each import of a module of a higher layer; a top-level module or folder in
    no layer is named too (a new one must be given its place)."""
    rank = {name: k for k, names in enumerate(layers) for name in names}
    wrong = []
    for module, taken in imports.items():
        parts = module.split(".")
        if len(parts) == 1:
            continue                                    # the package's face
        if parts[1] not in rank:
            wrong.append(f"{module} is in no layer")
            continue
        for target, _, line in taken:
            above = target.split(".")[1] if "." in target else None
            if above is not None and rank.get(above, -1) > rank[parts[1]]:
                wrong.append(f"{module}:{line} takes {target}")
    return wrong


def test_voxrender_has_no_import_circle_no_arrow_up_and_keeps_its_private_names():
    modules = modules_of(ROOT)
    imports = imports_of(modules)
    assert circles(modules, imports) == []
    assert arrows_up(imports) == []
    assert private_names_taken(imports) == []
    assert private_modules_taken(imports) == []


def test_the_checks_find_what_they_look_for(tmp_path):
    """A made package with one of each fault: a circle through an import inside a function, a private name taken
    by ``from``, one taken as an attribute, a private module taken from another package, an arrow up and a module in
    no layer."""
    package = tmp_path / "house"
    (package / "inner").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "a.py": "from . import b\n",
        "b.py": "def late():\n    from .a import thing\n",
        "c.py": "from .b import _helper\nfrom . import b\nb._other()\n",
        "inner/__init__.py": "",
        "inner/_hidden.py": "VALUE = 1\n",
        "inner/open.py": "from ._hidden import VALUE\n",
        "inner/up.py": "from .. import c\n",
        "d.py": "from .inner._hidden import VALUE\n",
    }
    for name, text in files.items():
        (package / name).write_text(text)
    modules = modules_of(package)
    imports = imports_of(modules)
    assert circles(modules, imports) == [["house.a", "house.b"]]
    assert private_names_taken(imports, oracles="nothing") == ["house.c:1 takes house.b._helper",
                                                                "house.c:3 takes house.b._other"]
    assert private_modules_taken(imports) == ["house.d:1 takes house.inner._hidden"]
    assert arrows_up(imports, layers=[("inner",), ("a", "b", "c")]) == ["house.d is in no layer",
                                                                        "house.inner.up:1 takes house.c"]


def test_every_mutant_of_the_mutation_gate_still_applies():
    """Each mutant of ``make mutants`` is one exact edit: a moved or reworded line would leave the gate refusing
    to run (or testing nothing), so the suite says so at once."""
    from mutants import MUTANTS

    def found(mutant):
        path = ROOT.parent / mutant.path
        return path.read_text(encoding="utf-8").count(mutant.old) if path.is_file() else 0

    assert [(m.name, m.path, found(m)) for m in MUTANTS if found(m) != 1] == []


def test_a_projection_is_a_kind_not_a_flag():
    """Nothing but the picture step (which holds ``RenderOptions.projection`` and hands it to ``project``) asks
    which projection a picture is: every other module asks the record, ``options.drawn`` (grey values? depth?
    labels?), so a new projection is one record in ``pictures/kinds.py``."""
    owners = {"voxrender.pictures._picture"}
    asking = []
    for module, path in modules_of(ROOT).items():
        if module in owners:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and node.attr == "projection" and isinstance(node.ctx, ast.Load):
                asking.append(f"{module}:{node.lineno}")
    assert asking == []


def test_one_idea_a_file():
    """No module over 700 lines, no function over 120, at most 15 modules and packages at the top of voxrender/:
    past those, a file holds more than one idea (issue 42)."""
    long_modules, long_functions = [], []
    for module, path in modules_of(ROOT).items():
        text = path.read_text(encoding="utf-8")
        if text.count("\n") > 700:
            long_modules.append(module)
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno >= 120:
                long_functions.append(f"{module}.{node.name}")
    top = [p.name for p in ROOT.iterdir() if p.name not in ("__init__.py", "__pycache__", "data")
           and (p.suffix == ".py" or (p / "__init__.py").is_file())]
    assert long_modules == [] and long_functions == [] and len(top) <= 15, (long_modules, long_functions, top)
