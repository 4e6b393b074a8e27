"""Pictures: an object's render shaded (``shade``), its labels looked up and coloured (``labels``,
``colours``), marked (``marks``), grey values windowed (``display``) and projected (``_project``); the
picture step of every command (``_picture``), and pictures compared (``compare``).
"""

from .._shared.face import face

_FACE = {
    "picture": "_picture",
    "RenderOptions": "_picture",
    "label_table": "_picture",
    "level_for": "_picture",
    "PROJECTIONS": "kinds",
    "SURFACE": "kinds",
    "project": "_project",
    "DisplayWindow": "display",
    "label_colours": "colours",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
