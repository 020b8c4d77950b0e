"""MkDocs hook: tables generated from the one definition, so that the docs cannot drift.

* ``<!-- parameters: STEM -->`` (a line of a system page) becomes the Markdown that
  ``descent-fmus info SYSTEM`` prints for the system ``STEM`` of the registry
  (:func:`descent_fmus.synthesis.cli.info.system_info`): every FMU of the system with its
  parameters' defaults, units and descriptions, read from the parameter dataclasses of
  ``models/``.  The generated title line is dropped and the other headings move down one
  level, under the page's own ``## Parameters`` section; characters that Markdown would read
  (``|`` in a description) are escaped.
* ``<!-- options: COMMAND [ACTION] -->`` (a line of the command-line reference) becomes the usage
  line and a table of every option of that command, read from the parser of ``descent-fmus``
  (:func:`descent_fmus.synthesis.cli.main.build_parser`).
* ``<!-- problem-file-format -->`` becomes the annotated TOML example, key by key, of the module
  docstring of :mod:`descent_fmus.synthesis.problems.files` (the reader of problem files).
* ``<!-- limits -->`` becomes the table of the documented maxima: every setting of the recipe
  (:mod:`descent_fmus.synthesis.methods.settings`), the problem's
  (:mod:`descent_fmus.synthesis.problems.limits`) and the run's
  (:mod:`descent_fmus.synthesis.run.resources`).
* ``<!-- operations -->`` becomes the tables of the network operator's unary and binary
  operations, read from the one operation table (:mod:`descent_fmus.models.controllers.
  operation_table`): number, name, guarded definition, unit element.

mkdocs.yml names this file under ``hooks:``; it imports the installed package.
"""
from __future__ import annotations

import argparse
import re

PARAMETERS = re.compile(r"^<!--\s*parameters:\s*([a-z_]+)\s*-->[ \t]*$", re.MULTILINE)
OPTIONS = re.compile(r"^<!--\s*options:\s*([a-z0-9_ -]+?)\s*-->[ \t]*$", re.MULTILINE)
FORMAT = re.compile(r"^<!--\s*problem-file-format\s*-->[ \t]*$", re.MULTILINE)
LIMITS = re.compile(r"^<!--\s*limits\s*-->[ \t]*$", re.MULTILINE)
OPERATIONS = re.compile(r"^<!--\s*operations\s*-->[ \t]*$", re.MULTILINE)


def parameter_section(stem: str) -> str:
    """The generated Markdown of one system, headings shifted under a page's ``##`` section."""
    from descent_fmus.synthesis.cli.info import system_info
    from descent_fmus.synthesis.registry import get_system

    _, text = system_info(get_system(stem))
    out = []
    for line in text.splitlines():
        if line.startswith("# "):
            continue                                   # the page has its own title
        if line.startswith("#"):
            line = "#" + line                          # "## X.fmu" -> "### X.fmu"
        elif line.startswith("| `"):
            name, default, unit, desc = line.split(" | ", 3)
            desc = desc[:-2].replace("\\|", "|")       # info escapes "|" for plain Markdown
            line = " | ".join((name, default, unit, _cell(desc))) + " |"
        out.append(line)
    return "\n".join(out).strip("\n")


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    text = " ".join(str(text).split())
    for ch in "\\|*_[]`":
        text = text.replace(ch, "\\" + ch)
    return text.replace("<", "&lt;").replace(">", "&gt;")


def _command_parser(words) -> argparse.ArgumentParser:
    from descent_fmus.synthesis.cli.main import build_parser

    parser = build_parser()
    for word in words:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[word]
    return parser


def options_section(command: str) -> str:
    """Usage line and a table of the options of ``descent-fmus COMMAND``."""
    parser = _command_parser(command.split())
    formatter = argparse.HelpFormatter(parser.prog, width=100)
    usage = parser.format_usage().strip()
    lines = ["```text", usage, "```", "", "| argument | meaning |", "| --- | --- |"]
    for group in parser._action_groups:
        rows = [a for a in group._group_actions
                if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction))]
        if not rows:
            continue
        if group.title not in ("positional arguments", "options", "optional arguments"):
            lines.append(f"| *{_cell(group.title)}* | |")
        for action in rows:
            name = formatter._format_action_invocation(action)
            text = formatter._expand_help(action) if action.help else ""
            lines.append(f"| `{name}` | {_cell(text)} |")
    return "\n".join(lines)


def problem_file_format() -> str:
    """The literal block after ``key by key::`` of the problem-file reader's docstring."""
    import textwrap

    from descent_fmus.synthesis.problems import files

    doc = files.__doc__
    head, sep, rest = doc.partition("key by key::")
    if not sep:
        raise ValueError("synthesis/problems/files.py: its docstring has no 'key by key::' block")
    block = []
    for line in rest.splitlines()[1:]:
        if line.strip() and not line.startswith("    "):
            break                                       # the first unindented line ends it
        block.append(line)
    return "```toml\n" + textwrap.dedent("\n".join(block)).strip("\n") + "\n```"


def limits_table() -> str:
    """Every documented maximum, read from where it is defined."""
    from descent_fmus.synthesis.methods.law import MAX_LAW_FILE_BYTES, MAX_NODES
    from descent_fmus.synthesis.methods.settings import settings_of
    from descent_fmus.synthesis.problems import limits
    from descent_fmus.synthesis.problems.contract import SETTING_GROUPS
    from descent_fmus.synthesis.run.resources import MAX_WORKERS
    lines = ["| what | command line | problem file | range |", "| --- | --- | --- | --- |"]
    for attr, cls, prefix in SETTING_GROUPS:
        for s in settings_of(cls):
            flag = "--" + (prefix + s.name).replace("_", "-")
            lines.append(f"| {_cell(s.help)} | `{flag}` | `[{attr}] {s.name}` | {s.limits} |")
    rows = [("local worker processes", "`--workers`", "", f"1..{MAX_WORKERS}"),
            ("initial states (listed, sampled or box corners)", "",
             "`[initial_states]`", f"<= {limits.MAX_STATES}"),
            ("communication steps per flight (stop time / step)", "", "`[simulation]`",
             f"<= {limits.MAX_STEPS}"),
            ("objectives, constraints, baseline structures", "", "`[[objectives]]`, "
             "`[[constraints]]`, `[baselines]`",
             f"<= {limits.MAX_OBJECTIVES}, {limits.MAX_CONSTRAINTS}, {limits.MAX_BASELINES}"),
            ("a problem file [bytes]", "`--problem`", "", f"<= {limits.MAX_FILE_BYTES}"),
            ("a law file [bytes]", "`--law`, `export-law`", "", f"<= {MAX_LAW_FILE_BYTES}"),
            ("nodes of a law's matrix (32 in the controller FMU)", "", "`[basic_law]`",
             f"<= {MAX_NODES}")]
    lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows]
    return "\n".join(lines)


def operations_table() -> str:
    """The unary and the binary operations, as the one operation table defines them."""
    from descent_fmus.models.controllers.operation_table import BINARY_OPS, UNARY_OPS

    def unit(v):
        return "NaN (the first arc sets the node)" if v != v else f"{v:g}"

    lines = ["| unary ρ | name | ρ(z) |", "| --- | --- | --- |"]
    lines += [f"| {op.number} | `{op.name}` | `{op.expr}` |" for op in UNARY_OPS[1:]]
    lines += ["", "| binary χ | name | χ(a, b): a the node's value, b the arc's | unit |",
              "| --- | --- | --- | --- |"]
    lines += [f"| {op.number} | `{op.name}` | `{op.expr}` | {unit(op.unit)} |"
              for op in BINARY_OPS[1:]]
    return "\n".join(lines)


def on_page_markdown(markdown, page, config, files):
    markdown = LIMITS.sub(lambda m: limits_table(), markdown)
    markdown = OPERATIONS.sub(lambda m: operations_table(), markdown)
    markdown = PARAMETERS.sub(lambda m: parameter_section(m.group(1)), markdown)
    markdown = FORMAT.sub(lambda m: problem_file_format(), markdown)
    return OPTIONS.sub(lambda m: options_section(m.group(1)), markdown)
