"""Names that become part of a path: the one rule, checked wherever a name turns into a file or directory name.

A method label (``--method``, an outside ``method.json``, a predictions root's folder name, a plugin's label, a
flow configuration or variant), a scene, a viewpoint, a scene preset or a study point id is *one* path component
under an output directory.  It is safe when it

- uses only ``A-Z a-z 0-9 _ . : + = -`` (so no path separator, no space, no NUL, nothing a shell or a file system
  treats specially),
- does not start with a dot (no hidden entries, no ``.`` or ``..``) and holds no ``..`` anywhere,
- is 1 to :data:`MAX_NAME_LENGTH` characters long.

Anything else is refused with one line naming where the name came from, so that no name can make tri360 write
outside the output directory it was given.
"""

from __future__ import annotations

import re

from harness.data.errors import UserError

__all__ = ["MAX_NAME_LENGTH", "NAME_CHARACTERS", "check_name", "is_safe_name"]

MAX_NAME_LENGTH = 100
NAME_CHARACTERS = "A-Za-z0-9_.:+=-"
_NAME_RE = re.compile(rf"[{NAME_CHARACTERS}]{{1,{MAX_NAME_LENGTH}}}")


def is_safe_name(name: object) -> bool:
    """True if ``name`` is a string usable as one path component (the rule of the module doc)."""
    return (isinstance(name, str) and _NAME_RE.fullmatch(name) is not None and not name.startswith(".")
            and ".." not in name)


def check_name(name: str, source: str) -> str:
    """Return ``name`` if it is safe as one path component (see the module doc), else refuse it.

    Args:
        name: the name, from anywhere (untrusted).
        source: where it came from, for the message: ``--method``, a ``method.json`` path, ``frame.json (scene)``.
    Raises:
        UserError: one line naming ``source``, the name and the rule it breaks.
    """
    if is_safe_name(name):
        return name
    if not isinstance(name, str):
        why = f"is a {type(name).__name__}, not a string"
    elif not name:
        why = "is empty"
    elif len(name) > MAX_NAME_LENGTH:
        why = f"is {len(name)} characters long (at most {MAX_NAME_LENGTH})"
    elif "/" in name or "\\" in name:
        why = "contains a path separator"
    elif ".." in name:
        why = "contains '..'"
    elif name.startswith("."):
        why = "starts with a dot"
    else:
        bad = sorted({c for c in name if not re.fullmatch(f"[{NAME_CHARACTERS}]", c)})
        why = "contains " + ", ".join(repr(c) for c in bad[:5])
    shown = name if not isinstance(name, str) or len(name) <= 60 else name[:57] + "..."
    raise UserError(f"{source}: name {shown!r} {why}; a name that becomes part of a path may use only letters, "
                    f"digits and _ . : + = - (no leading dot, no '..', at most {MAX_NAME_LENGTH} characters)")
