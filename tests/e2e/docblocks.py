"""The command and code blocks of the documentation, read from the Markdown itself.

A block is a fenced block (three backticks), a block indented by four spaces after a blank line,
or (README only) an inline code span that is a command or a request: it starts with ``trajopt ``,
``GET /``, ``{"``, is a member of a request (``"name": {`` or ``"name": [``) or a quoted message
(``infeasible ``, ``raise ``). A test names its block by
the document and the start of its text (an inline span by its whole text), and runs the
document's text. :func:`inline_spans` gives every inline span of a document, for the commands
its prose names (tests/unit/test_documented_bench_commands.py).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = ("README.md", "docs/problem-contract.md", "docs/service.md")
"""The documents whose every block a case of tests/e2e/test_documented_commands.py runs."""
INLINE_DOCUMENTS = ("README.md",)
"""The documents whose inline commands are blocks too."""
INLINE_STARTS = ("trajopt ", "GET /", '{"', "infeasible ", "raise ")
_MEMBER = re.compile(r'"\w+": [\[{]')
"""A member of a JSON request quoted alone (``"name": {...}``)."""
_SPAN = re.compile(r"(?<!`)`([^`]+)`(?!`)")


@dataclass(frozen=True)
class Block:
    """One block: where it is, how it is written and its text (indentation removed)."""

    document: str
    line: int
    kind: str
    text: str

    def matches(self, document: str, key: str) -> bool:
        """Whether ``key`` names this block of ``document``: an inline span by its whole text,
        a block by the start of its text."""
        if self.document != document:
            return False
        text = self.text.strip()
        return text == key if self.kind == "inline" else text.startswith(key)


def _indented(lines: list[str], start: int) -> int:
    """The end (exclusive) of the indented block that starts at ``start``."""
    end = start
    while end < len(lines):
        following = lines[end + 1] if end + 1 < len(lines) else ""
        blank_inside = not lines[end].strip() and following.startswith("    ")
        if not (lines[end].startswith("    ") or blank_inside):
            break
        end += 1
    return end


def _spans(document: str, prose: str) -> list[Block]:
    """Every inline code span of ``prose`` (blocks blanked out), its white space one space each
    (a span may wrap across lines)."""
    found = []
    for match in _SPAN.finditer(prose):
        line = prose.count("\n", 0, match.start()) + 1
        found.append(Block(document, line, "inline", " ".join(match.group(1).split())))
    return found


def _inline(document: str, prose: str) -> list[Block]:
    """The inline code spans of ``prose`` that are commands or requests."""
    return [
        span
        for span in _spans(document, prose)
        if span.text.startswith(INLINE_STARTS) or _MEMBER.match(span.text)
    ]


def _split(document: str) -> tuple[list[Block], str]:
    """The blocks of ``document`` (a path relative to the repository root), in order, and its
    prose: its text with every block's lines blank, so a line number stays the document's."""
    text = (REPO_ROOT / document).read_text(encoding="utf-8")
    lines = text.split("\n")
    blocks: list[Block] = []
    prose: list[str] = []
    i = 0
    while i < len(lines):
        if lines[i].startswith("```"):
            end = i + 1
            while not lines[end].startswith("```"):
                end += 1
            blocks.append(Block(document, i + 1, "fenced", "\n".join(lines[i + 1 : end])))
            prose.extend([""] * (end + 1 - i))
            i = end + 1
        elif lines[i].startswith("    ") and (i == 0 or not lines[i - 1].strip()):
            end = _indented(lines, i)
            body = "\n".join(line[4:] for line in lines[i:end]).rstrip()
            blocks.append(Block(document, i + 1, "indented", body))
            prose.extend([""] * (end - i))
            i = end
        else:
            prose.append(lines[i])
            i += 1
    return blocks, "\n".join(prose)


def read_blocks(document: str) -> list[Block]:
    """Every block of ``document`` (a path relative to the repository root), in order."""
    blocks, prose = _split(document)
    if document in INLINE_DOCUMENTS:
        blocks.extend(_inline(document, prose))
    return blocks


def inline_spans(document: str) -> list[Block]:
    """Every inline code span of ``document`` outside its blocks, whatever its text: for the
    commands a document names in its prose."""
    return _spans(document, _split(document)[1])


def all_blocks() -> list[Block]:
    """The blocks of every document of :data:`DOCUMENTS`."""
    return [block for document in DOCUMENTS for block in read_blocks(document)]


def block(document: str, key: str) -> Block:
    """The one block of ``document`` that ``key`` names (see :meth:`Block.matches`)."""
    found = [b for b in read_blocks(document) if b.matches(document, key)]
    assert len(found) == 1, (document, key, found)
    return found[0]
