"""The type stubs (lightstage/__init__.pyi) say what the module has: every public name, and each
job's parameters in order with their defaults."""

import ast
import pathlib
import re

import lightstage as ls

STUBS = pathlib.Path(ls.__file__).with_name("__init__.pyi")


def stub_functions():
    tree = ast.parse(STUBS.read_text())
    return {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}


def runtime_parameters(function):
    """Parameter names of a pybind11 function, from its signature line."""
    first = function.__doc__.splitlines()[0]
    inside = first[first.index("(") + 1:first.rindex(") ->")]
    parts, depth, current = [], 0, ""
    for ch in inside:  # Split at the commas outside brackets.
        depth += ch in "[(" and 1 or (ch in "])" and -1 or 0)
        if ch == "," and depth == 0:
            parts.append(current)
            current = ""
        else:
            current += ch
    parts.append(current)
    return [part.split(":")[0].strip() for part in parts if part.strip()]


def test_every_public_name_has_a_stub():
    text = STUBS.read_text()
    for name in ls.__all__:
        assert re.search(rf"\b(class|def) {name}\b|import {name} as {name}", text), name


def test_job_parameters_match():
    stubs = stub_functions()
    for name in ("capture", "build", "relight", "fit", "normals", "import_set", "compress",
                 "render", "read_image"):
        stub = stubs[name]
        expected = [a.arg for a in stub.args.args]
        if stub.args.kwonlyargs:
            expected += ["*"] + [a.arg for a in stub.args.kwonlyargs]
        assert runtime_parameters(getattr(ls, name)) == expected, name
        assert ast.get_docstring(stub), name


COMMANDS = {"capture": "capture", "build": "build", "relight": "relight", "fit": "fit",
            "normals": "normals", "import_set": "import", "compress": "compress",
            "render": "render"}


def documented_parameters(docstring):
    """The stub's "name: text" entries (text joined across its indented lines)."""
    entries, name = {}, None
    for line in docstring.splitlines():
        match = re.match(r"^(\w+): (.*)$", line)
        if match:
            name = match.group(1)
            entries[name] = match.group(2)
        elif name and line.startswith("    "):
            entries[name] += " " + line.strip()
        else:
            name = None
    return entries


def test_docstrings_are_the_help_texts(cli):
    stubs = stub_functions()
    for function, command in COMMANDS.items():
        help_text = " ".join(cli(command, "--help").stdout.split())
        entries = documented_parameters(ast.get_docstring(stubs[function]))
        assert entries, function
        for name, text in entries.items():
            # A flag that turns an option off says which first: "False (--no-x): help".
            text = re.sub(r"^False(?: \(--[\w-]+\))?: ", "", text)
            # Its first sentence (what follows may say what the keyword adds, e.g. out=None).
            sentence = " ".join(text.split()).split(". ")[0][:40]
            assert sentence in help_text, (function, name, sentence)
