"""The literal oracles stand apart from the code they check (see ``voxrender/_render/literal/__init__.py``)."""

import ast
from pathlib import Path

import voxrender

PACKAGE = Path(voxrender.__file__).parent
LITERAL = PACKAGE / "_render" / "literal"


def imported(path):
    """The absolute names of the modules (or, for ``from package import name``, the names) ``path`` imports."""
    package = ".".join(path.relative_to(PACKAGE.parent).parent.parts)
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
            module = ".".join(base + [node.module] if node.module else base)
            for alias in node.names:          # a module taken from its package counts as that module
                submodule = f"{module}.{alias.name}"
                is_module = PACKAGE.parent.joinpath(*submodule.split(".")).with_suffix(".py").exists()
                names.add(submodule if is_module or not node.module else module)
    return names


def test_the_literal_versions_take_only_the_region_octree_from_voxrender():
    assert len(list(LITERAL.glob("*.py"))) >= 7
    for path in LITERAL.glob("*.py"):
        taken = {name for name in imported(path) if name.partition(".")[0] == "voxrender"}
        assert {name for name in taken
                if not name.startswith("voxrender._render.literal")} <= {"voxrender.object.octree"}, path.name


def test_no_production_module_imports_the_literal_versions():
    for path in PACKAGE.rglob("*.py"):
        if LITERAL not in path.parents:
            assert not any(name.startswith("voxrender._render.literal") for name in imported(path)), path
