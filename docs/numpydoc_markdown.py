"""The reStructuredText in the numpydoc docstrings, as the Markdown that mkdocstrings renders.

The docstrings are numpydoc, as scikit-image's are: they name other objects with Sphinx roles
(``:func:`read_volume```), show doctests outside an Examples section, and end a paragraph with ``::`` before a
literal block. mkdocstrings reads the numpydoc sections but not these, so this griffe extension (``mkdocs.yml``:
the python handler's ``extensions``) rewrites each docstring before it is parsed:

- a role becomes an optional cross-reference, its name resolved in the scope of the docstring's object: a link
  where the manual documents the object, plain code where it does not, and never a warning;
- a doctest outside the Examples section (which mkdocstrings already shows as code) becomes a code block;
- a paragraph's closing ``::`` becomes ``:`` (the indented block after it is code in Markdown too).
"""

import re

import griffe

ROLE = re.compile(r":(?:class|func|meth|data|attr|mod|exc|obj):`(~?)([\w.]+)(?:\(\))?`")
SECTION_RULE = re.compile(r"^\s*-{3,}\s*$")


def _identifier(obj, name):
    """The full path of ``name`` as the docstring of ``obj`` means it (``None`` when it names nothing known)."""
    if name.startswith("."):  # relative to the package, as in an import
        package = obj.module if obj.module.is_package else obj.module.parent
        return package.path + name
    first, _, rest = name.partition(".")
    if rest and first not in obj.module.members:
        return name  # already a full path: voxrender.io.Volume, numpy.lexsort
    try:
        found = obj.resolve(first)
    except griffe.NameResolutionError:
        return None
    return f"{found}.{rest}" if rest else found


def _reference(obj, match):
    short, name = match.groups()
    title = f"<code>{name.rsplit('.', 1)[-1] if short else name}</code>"
    identifier = _identifier(obj, name)
    return f'<autoref identifier="{identifier}" optional>{title}</autoref>' if identifier else title


def _fence_doctests(text):
    """Doctests outside the Examples section (a prompt line, its continuations and output) as code blocks."""
    lines, out, section, in_doctest = text.splitlines(), [], None, False
    for number, line in enumerate(lines):
        if number + 1 < len(lines) and SECTION_RULE.match(lines[number + 1]) and line.strip():
            section = line.strip()
        starts = line.lstrip().startswith(">>>")
        if section != "Examples" and starts and not in_doctest:
            indent = line[: len(line) - len(line.lstrip())]
            if out and out[-1].strip():
                out.append("")
            out.append(indent + "```pycon")
            in_doctest = True
        elif in_doctest and not line.strip():
            out.append(indent + "```")
            in_doctest = False
        out.append(line)
    if in_doctest:
        out.append(indent + "```")
    return "\n".join(out)


class NumpydocMarkdown(griffe.Extension):
    """Rewrite every docstring's reStructuredText before mkdocstrings parses it."""

    def on_object(self, *, obj, **kwargs):
        """Griffe calls this once per object (module, class, function, attribute) of the loaded package."""
        if obj.docstring is None:
            return
        text = _fence_doctests(obj.docstring.value)
        text = re.sub(r"(\S)::$", r"\1:", text, flags=re.MULTILINE)
        obj.docstring.value = ROLE.sub(lambda match: _reference(obj, match), text)
