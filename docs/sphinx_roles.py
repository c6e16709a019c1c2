"""A Griffe extension for the API reference (mkdocs.yml): Sphinx roles in docstrings as links.

The docstrings are numpydoc and cross-reference with Sphinx roles (:class:`~chaplygin.System`,
:func:`write_report`, :attr:`parameters`), which mkdocstrings would print as they are. Each role
becomes its name in code font, linked to the object's entry in the reference where it has one
(an "optional" cross-reference of mkdocs-autorefs: no link, and no warning, where it has none).
As in Sphinx, ``~`` shows only the last part of the name, ``text <target>`` shows the text, and
functions and methods get ``()``.
"""

from __future__ import annotations

import html
import re
from typing import Any

from griffe import Extension, Module, NameResolutionError, Object

ROLE = re.compile(r":(?:py:)?(class|func|meth|attr|data|mod|exc|obj|const):`([^`]+)`")


def _target(obj: Object, name: str) -> str:
    """The full path of ``name`` as seen from ``obj``'s docstring (``name`` itself if unknown)."""
    if name.startswith("chaplygin."):
        return name
    head, _, rest = name.partition(".")
    for scope in (obj, obj.parent):
        if scope is None:
            continue
        try:
            resolved = scope.resolve(head)
        except (NameResolutionError, AttributeError):
            continue
        return f"{resolved}.{rest}" if rest else resolved
    return name


def convert(text: str, obj: Object) -> str:
    """``text`` with every Sphinx role replaced by an optional cross-reference."""

    def one(match: re.Match[str]) -> str:
        role, body = match.groups()
        explicit = re.fullmatch(r"(.*?)\s*<([^<>]+)>", body)
        if explicit:
            shown, name = explicit.group(1), explicit.group(2)
        else:
            name = body.lstrip("~!")
            shown = name.rsplit(".", 1)[-1] if body.startswith("~") else name
            if role in ("func", "meth") and not shown.endswith(")"):
                shown += "()"
        identifier = html.escape(_target(obj, name), quote=True)
        return f'<autoref identifier="{identifier}" optional><code>{html.escape(shown)}</code></autoref>'

    return ROLE.sub(one, text)


class SphinxRoles(Extension):
    """Rewrites the docstrings of a package once it is loaded (names resolve by then)."""

    def on_package(self, *, pkg: Module, **kwargs: Any) -> None:
        seen: set[int] = set()

        def walk(obj: Object) -> None:
            if id(obj) in seen:
                return
            seen.add(id(obj))
            if obj.docstring is not None:
                obj.docstring.value = convert(obj.docstring.value, obj)
            for member in obj.members.values():
                if not member.is_alias:
                    walk(member)  # type: ignore[arg-type]

        walk(pkg)
