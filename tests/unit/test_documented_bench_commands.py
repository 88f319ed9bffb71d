"""Every ``python -m`` command of docs/methods/*.md, docs/security-operations.md and
docs/architecture.md, checked against its module's own argument parser without running it.

Most are benchmarks that take minutes to hours (they cannot run in CI); what can rot is the
command itself: a renamed module, a flag or a file that changed. So each command is read from
the Markdown (tests/e2e/docblocks.py: block lines, and inline spans, which may wrap across
lines), its module must exist, and the parser its ``main()`` uses (the module's ``parser()``;
``app.cli``'s ``_build_parser()``; for ``pytest``, the running session's option parser) must
accept exactly the documented arguments. A documented argument that names a file of the
repository (it has a ``/``) must exist. A span written without its ``python -m``
(``bench.foh_table4 --repeats 3``) is the same command. ``trajopt`` is the console script of
``app.cli``, so the ``trajopt keys`` lines of docs/security-operations.md are checked with its
parser as well (running them needs the service's database and, for ``create``, api-keys mode).

Placeholders are replaced by a real example, never skipped (:data:`PLACEHOLDERS`):
``<doc>`` by docs/examples/user-free-time-min-heat.json (the problem the table measures);
``<a foh-ptr result>`` and ``<the foh-ptr result>`` by tests/golden/data/foh-us76.json (a
foh-ptr result document; docs/examples holds problems only); ``<case>`` by
``rlv-min-heat-load`` (a golden case); ``[--client NAME]`` by ``--client flight-dynamics``;
``KEY_ID`` by a key id prefix. A placeholder not in that table fails.

What is not checked, and why (:data:`NOT_COMMANDS`, :data:`NOT_COMMAND_BLOCKS`; every other
block line, and every other span that starts with ``python``, fails
:func:`test_every_block_line_and_python_span_is_known`):

- docs/security-operations.md, ``export TRAJOPT_API_KEY_SECRET="$(openssl rand -hex 32)"``:
  it sets a secret in the operator's shell, from openssl; no command of this repository.
  :func:`test_the_exported_secret_is_a_setting` checks that the service reads that variable.
- docs/architecture.md, the block that starts ``request schema``: a diagram of the data flow
  (folders and modules), no command.
- docs/methods/README.md, ``python -c "from app.cli import main; ..."``: the comparison the
  text describes, elided (``...``), not a command to copy.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import io
import re
import shlex
from collections.abc import Callable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass

import pytest

from app.settings import Settings
from tests.e2e.docblocks import REPO_ROOT, Block, inline_spans, read_blocks

SECURITY = "docs/security-operations.md"
ARCHITECTURE = "docs/architecture.md"
DOCUMENTS = (
    ARCHITECTURE,
    SECURITY,
    *sorted(str(p.relative_to(REPO_ROOT)) for p in (REPO_ROOT / "docs/methods").glob("*.md")),
)
"""The documents whose commands are checked here (the others' run in tests/e2e)."""

PLACEHOLDERS = {
    "<doc>": "docs/examples/user-free-time-min-heat.json",
    "<a foh-ptr result>": "tests/golden/data/foh-us76.json",
    "<the foh-ptr result>": "tests/golden/data/foh-us76.json",
    "<case>": "rlv-min-heat-load",
    "[--client NAME]": "--client flight-dynamics",
    "KEY_ID": "0f3a9c",
}
"""Each placeholder the documents write, and the real example a check puts in its place."""
_PLACEHOLDER = re.compile(r"<[^<>]*>|\[[^\[\]]*\]")
"""A placeholder (``<...>`` or ``[...]``) that :data:`PLACEHOLDERS` does not know."""

NOT_COMMANDS = {
    (SECURITY, "export TRAJOPT_API_KEY_SECRET="): "sets the operator's shell; no command here",
    ("docs/methods/README.md", 'python -c "from app.cli import main; ..."'): "elided, not run",
}
"""Block lines and spans that are no command to check, by document and start."""
NOT_COMMAND_BLOCKS = {(ARCHITECTURE, "request schema "): "a diagram of the data flow"}
"""Whole blocks that are no command, by document and the start of their text."""

PARSER_FUNCTIONS = {"app.cli": "_build_parser"}
"""A module whose parser function is not called ``parser``."""
_BARE_MODULE = re.compile(r"(?:app|bench|tests|worker)(?:\.\w+)+ -")
"""A span that is a command written without its ``python -m``."""
_PYTHON_M = re.compile(r"python\s+-m\b")


@dataclass(frozen=True)
class Command:
    """A documented command: where it is, as written, and its module and arguments (every
    placeholder replaced by its example)."""

    document: str
    line: int
    text: str
    module: str
    args: tuple[str, ...]

    def where(self) -> str:
        """The document, line and command, for a failure message."""
        return f"{self.document}:{self.line}: `{self.text}`"


def command(document: str, line: int, text: str) -> Command:
    """The :class:`Command` that ``text`` (``python -m``, ``trajopt`` or a bare module) is."""
    runnable = text
    for placeholder, example in PLACEHOLDERS.items():
        runnable = runnable.replace(placeholder, example)
    words = shlex.split(runnable, comments=True)
    if words[:2] == ["python", "-m"]:
        words = words[2:]
    elif words[0] == "trajopt":
        words = ["app.cli", *words[1:]]
    return Command(document, line, text, words[0], tuple(words[1:]))


def _is_command(text: str, span: bool = False) -> bool:
    """Whether a block line (or a span) is a command this module checks; a ``trajopt`` span
    names a subcommand in prose (``trajopt solve``), a ``trajopt`` block line is a command."""
    starts = ("python -m ",) if span else ("python -m ", "trajopt ")
    return text.startswith(starts) or bool(_BARE_MODULE.match(text))


def block_lines(block: Block) -> list[tuple[int, str]]:
    """The lines of a block with their line numbers in the document, continued lines (a
    trailing backslash) joined, blank and comment lines dropped."""
    first = block.line + 1 if block.kind == "fenced" else block.line
    found: list[tuple[int, str]] = []
    pending: tuple[int, str] | None = None
    for offset, raw in enumerate(block.text.split("\n")):
        start, text = pending or (first + offset, "")
        text = f"{text} {raw.strip()}".strip()
        pending = (start, text[:-1]) if text.endswith("\\") else None
        if pending is None and text and not text.startswith("#"):
            found.append((start, text))
    return found


def _known(document: str, text: str, table: dict[tuple[str, str], str] = NOT_COMMANDS) -> bool:
    """Whether ``text`` (a block line or a span; a block with ``table``
    :data:`NOT_COMMAND_BLOCKS`) is one of ``table``'s."""
    return any(doc == document and text.startswith(start) for doc, start in table)


def documented_commands(document: str) -> list[Command]:
    """Every command of ``document``: its block lines, then its inline spans."""
    found = []
    for block in read_blocks(document):
        if not _known(document, block.text, NOT_COMMAND_BLOCKS):
            found.extend(command(document, n, t) for n, t in block_lines(block) if _is_command(t))
    for span in inline_spans(document):
        if _is_command(span.text, span=True):
            found.append(command(document, span.line, span.text))
    return found


COMMANDS = [c for document in DOCUMENTS for c in documented_commands(document)]


def module_parser(module: str) -> argparse.ArgumentParser:
    """The argument parser that ``python -m module`` uses (a package's is its ``__main__``'s)."""
    imported = importlib.import_module(module)
    if hasattr(imported, "__path__"):
        imported = importlib.import_module(f"{module}.__main__")
    build: Callable[[], argparse.ArgumentParser] = getattr(
        imported, PARSER_FUNCTIONS.get(module, "parser")
    )
    return build()


def parse_error(found: Command, pytest_parser: Callable[[list[str]], object]) -> str | None:
    """What the module's own parser says against the command's arguments (None: accepted)."""
    if found.module == "pytest":
        try:
            pytest_parser(list(found.args))
        except pytest.UsageError as exc:
            return str(exc)
        return None
    printed = io.StringIO()
    try:
        with redirect_stderr(printed), redirect_stdout(printed):
            module_parser(found.module).parse_args(list(found.args))
    except SystemExit as exc:
        if exc.code:  # argparse's last line, "<prog>: error: <message>"; prog is pytest's here
            return "error: " + printed.getvalue().strip().splitlines()[-1].split("error: ", 1)[-1]
    return None


def problem(found: Command, pytest_parser: Callable[[list[str]], object]) -> str | None:
    """Why ``found`` would not run as documented (None: its module exists and parses it)."""
    unknown = _PLACEHOLDER.findall(" ".join(found.args))
    if unknown:
        return f"{found.where()}: placeholder {unknown} has no example in PLACEHOLDERS"
    try:
        exists = importlib.util.find_spec(found.module) is not None
    except ModuleNotFoundError:
        exists = False
    if not exists:
        return f"{found.where()}: module {found.module} does not exist"
    missing = [a for a in found.args if "/" in a and not (REPO_ROOT / a).exists()]
    if missing:
        return f"{found.where()}: no such file {missing}"
    error = parse_error(found, pytest_parser)
    return f"{found.where()}: {error}" if error else None


@pytest.fixture
def pytest_parser(pytestconfig: pytest.Config) -> Callable[[list[str]], object]:
    """pytest's own option parser: the running session's, which knows every plugin's options."""
    return pytestconfig._parser.parse


@pytest.mark.parametrize("found", COMMANDS, ids=lambda c: f"{c.document}:{c.line}")
def test_documented_command_parses(
    found: Command, pytest_parser: Callable[[list[str]], object]
) -> None:
    """Each documented command names a module whose own parser accepts its arguments."""
    assert problem(found, pytest_parser) is None, problem(found, pytest_parser)


def test_every_document_has_its_commands_found() -> None:
    """Every ``python -m`` written in a document (however wrapped) is one checked command, so
    a command the reader misses fails here instead of going unchecked."""
    for document in DOCUMENTS:
        text = (REPO_ROOT / document).read_text(encoding="utf-8")
        written = len(_PYTHON_M.findall(" ".join(text.split())))
        found = [c for c in COMMANDS if c.document == document and c.text.startswith("python")]
        assert found, f"{document}: no command found"
        assert written == len(found), (document, written, [c.text for c in found])


def test_every_block_line_and_python_span_is_known() -> None:
    """Every block line, and every span that starts with ``python``, is a checked command or
    one of :data:`NOT_COMMANDS` (whose reasons the module docstring gives): no silent skip."""
    unknown = []
    for document in DOCUMENTS:
        for block in read_blocks(document):
            if not _known(document, block.text, NOT_COMMAND_BLOCKS):
                lines = block_lines(block)
                unknown += [
                    (document, n, t)
                    for n, t in lines
                    if not _is_command(t) and not _known(document, t)
                ]
        for span in inline_spans(document):
            if span.text.startswith("python") and not _is_command(span.text, span=True):
                unknown += [(document, span.line, span.text)] * (not _known(document, span.text))
    assert not unknown, f"neither checked nor explained in this module's docstring: {unknown}"


def test_the_exported_secret_is_a_setting() -> None:
    """The variable docs/security-operations.md exports is one the service's settings read."""
    lines = [t for b in read_blocks(SECURITY) for _, t in block_lines(b)]
    exported = [re.match(r"export (\w+)=", t) for t in lines if t.startswith("export ")]
    prefix = str(Settings.model_config.get("env_prefix", ""))
    fields = {f"{prefix}{name}".upper() for name in Settings.model_fields}
    assert exported and all(m and m.group(1) in fields for m in exported), exported


def test_a_wrong_flag_fails_naming_the_document_line_and_command(
    pytest_parser: Callable[[list[str]], object],
) -> None:
    """The check itself: a flag the parser lacks fails, naming where and what."""
    found = command("docs/x.md", 7, "python -m bench.variants --onyl foh-us76")
    message = str(problem(found, pytest_parser))
    assert message.startswith("docs/x.md:7: `python -m bench.variants --onyl foh-us76`: "), message
    assert message.endswith("error: unrecognized arguments: --onyl foh-us76"), message
    wrapped = command("docs/x.md", 8, "python -m pytest tests/unit --no-such-option")
    assert "--no-such-option" in str(problem(wrapped, pytest_parser))


def test_a_missing_module_or_file_or_placeholder_fails(
    pytest_parser: Callable[[list[str]], object],
) -> None:
    """The check itself: a module that does not exist, a missing file and an unknown
    placeholder each fail, naming the command."""
    assert problem(command("d.md", 1, "python -m bench.no_such --x"), pytest_parser) == (
        "d.md:1: `python -m bench.no_such --x`: module bench.no_such does not exist"
    )
    assert "does not exist" in str(problem(command("d.md", 2, "python -m nope.x"), pytest_parser))
    missing = command("d.md", 3, "python -m bench.nlp_reference docs/examples/gone.json")
    assert "no such file ['docs/examples/gone.json']" in str(problem(missing, pytest_parser))
    unknown = command("d.md", 4, "python -m bench.nlp_reference <some doc>")
    assert "placeholder ['<some doc>']" in str(problem(unknown, pytest_parser))
