"""A griffe extension for the API reference: three fixes of docstring markup, made for the
site only (the library's docstrings are not edited).

1. **Units after a bracket.** The project writes units in brackets (``r [N]``). Right after
   another bracket, ``[J_e^T r ; r_f] [N]`` is Markdown's reference-link syntax, and
   mkdocs-autorefs looks for an object called ``N``. The unit's bracket is escaped
   (``] \\[N]``), so it prints as written.
2. **Prose after a numpy section's items.** A paragraph at column 0 after the items of a
   ``Parameters`` (or ``Other Parameters``, ``Attributes``, ``Raises``) section, such as
   ``:attr:`stats` counts what actually ran``, is not an item. griffe's numpy parser warns
   and drops it. Such a paragraph is moved to the end of the description, above the first
   section, so it is shown.
3. **Free-form items.** The project writes a section's items on one line as
   ``name : what it is, with its shape and unit``, wrapped onto indented lines when long,
   where numpy's style means ``name : type`` with the description below. Such an item
   becomes ``name`` with its text as the description, so the site shows
   ``points – (n, 3) float [mm]`` rather than a "type" that is a sentence.

Each fix rewrites ``obj.docstring.value`` before griffe parses it. The parse runs lazily, when
mkdocstrings renders the object.
"""

from __future__ import annotations

import re

import griffe

UNIT_AFTER_BRACKET = re.compile(r"\] \[")
CODE_SPAN = re.compile(r"(`+[^`]*`+)")
ITEM_SECTIONS = {"parameters", "other parameters", "attributes", "keyword arguments", "raises", "warns"}
ALL_ITEM_SECTIONS = ITEM_SECTIONS | {"returns", "yields", "receives", "raises", "warns"}
NAMED_ITEM = re.compile(r"^(?P<names>\*{0,2}[A-Za-z_]\w*(\s*,\s*\*{0,2}[A-Za-z_]\w*)*)\s*:\s+(?P<text>\S.*)$")
# an item line of those sections: "name", "name : type", "*args", "a, b : float"
ITEM = re.compile(r"^\*{0,2}[A-Za-z_][\w]*(\s*,\s*\*{0,2}[A-Za-z_]\w*)*\s*(:.*)?$")


def escape_units(text: str) -> str:
    """``] [`` outside code spans becomes ``] \\[`` (a unit in brackets after a bracket)."""
    parts = CODE_SPAN.split(text)  # odd parts: the code spans
    return "".join(UNIT_AFTER_BRACKET.sub(r"] \\[", p) if k % 2 == 0 else p for k, p in enumerate(parts))


def _is_header(lines: list[str], i: int) -> bool:
    return (i + 1 < len(lines) and lines[i].strip() != "" and not lines[i].startswith(" ")
            and re.fullmatch(r"-{3,}", lines[i + 1].strip() or "x") is not None
            and len(lines[i + 1].strip()) >= len(lines[i].strip()) - 1)


def move_section_prose(text: str) -> str:
    """``text`` with column-0 paragraphs that follow an item section's items moved up to
    the end of the description (before the first section header)."""
    lines = text.split("\n")
    headers = [i for i in range(len(lines)) if _is_header(lines, i)]
    if not headers:
        return text
    kept: list[str] = lines[:headers[0]]
    moved: list[list[str]] = []
    i = headers[0]
    section = None
    while i < len(lines):
        if _is_header(lines, i):
            section = lines[i].strip().lower()
            kept += lines[i:i + 2]
            i += 2
            continue
        line = lines[i]
        starts_paragraph = i > 0 and lines[i - 1].strip() == "" and line.strip() != ""
        if (section in ITEM_SECTIONS and starts_paragraph and not line.startswith(" ")
                and not ITEM.match(line.strip())):
            j = i
            while j < len(lines) and lines[j].strip() != "" and not _is_header(lines, j):
                j += 1
            moved.append(lines[i:j])
            while kept and kept[-1].strip() == "":
                kept.pop()
            i = j
            continue
        kept.append(line)
        i += 1
    if not moved:
        return text
    head, first = kept[:headers[0]], kept[headers[0]:]
    while head and head[-1].strip() == "":
        head.pop()
    for paragraph in moved:
        head += [""] + paragraph
    return "\n".join(head + [""] + first)


def items_as_descriptions(text: str) -> str:
    """``name : text`` items (and their indented continuation lines) of the item sections
    rewritten as ``name`` with ``text`` as its indented description."""
    lines = text.split("\n")
    out: list[str] = []
    section = None
    i = 0
    while i < len(lines):
        if _is_header(lines, i):
            section = lines[i].strip().lower()
            out += lines[i:i + 2]
            i += 2
            continue
        match = NAMED_ITEM.match(lines[i]) if section in ALL_ITEM_SECTIONS and not lines[i].startswith(" ") else None
        if match is None:
            out.append(lines[i])
            i += 1
            continue
        j = i + 1
        while j < len(lines) and lines[j].startswith((" ", "\t")) and lines[j].strip():
            j += 1
        rest = lines[i + 1:j]
        indent = min((len(r) - len(r.lstrip()) for r in rest), default=0)
        out.append(match["names"])
        out += ["    " + match["text"]] + ["    " + r[indent:] for r in rest]
        i = j
    return "\n".join(out)


class DocstringMarkup(griffe.Extension):
    """Applies the fixes of the module docstring to every object's docstring."""

    def on_instance(self, *, node, obj, agent, **kwargs) -> None:
        if obj.docstring is None:
            return
        obj.docstring.value = items_as_descriptions(move_section_prose(escape_units(obj.docstring.value)))
