#!/usr/bin/env bash
# Keeps docs/cli.md and the CLI's --help in step, and the docs' links whole (the cli_doc test):
#   1. runs `lightstage [CMD [SUB]] --help` for every command and subcommand (found from the
#      "Subcommands:" lists of --help itself);
#   2. fails, naming them, where an option --help prints is missing from the command's section of
#      docs/cli.md (a heading "lightstage CMD [SUB]"), where that section names an option (--xyz)
#      that --help does not know, or where a command has no section (or a section no command).
#      On a line that names another command ("lightstage fit --time"), the options after it are
#      checked against that command instead;
#   3. fails where a relative link in README.md or docs/*.md does not resolve to a file in the
#      tree, or its #anchor to a heading of that file.
#   scripts/check_cli_doc.sh [LIGHTSTAGE]   (default: build/app/cli/lightstage)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cli="${1:-$root/build/app/cli/lightstage}"
[ -x "$cli" ] || { echo "check_cli_doc: no executable $cli (build the lightstage target first)"; exit 1; }
exec python3 - "$root" "$cli" <<'PY'
import os
import re
import subprocess
import sys

root, cli = sys.argv[1], sys.argv[2]
problems = []

# --- 1. What --help says -------------------------------------------------------------------------
OPTION_LINE = re.compile(r"^  (?:-[A-Za-z0-9],)?(--[A-Za-z0-9][A-Za-z0-9_-]*)")
SUBCOMMAND_LINE = re.compile(r"^  ([a-z][A-Za-z0-9_-]*)(\s|$)")


def help_text(path):
    run = subprocess.run([cli, *path, "--help"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         text=True, timeout=60)
    if run.returncode != 0:
        problems.append(f"'lightstage {' '.join(path)} --help' exited with {run.returncode}")
    return run.stdout


def parse_help(text):
    options, subcommands, section = set(), [], None
    for line in text.splitlines():
        if re.match(r"^[A-Za-z][A-Za-z ]*:\s*$", line):
            section = line.strip().rstrip(":").lower()
            continue
        if not line.strip():
            if section == "subcommands":
                section = None
            continue
        m = OPTION_LINE.match(line)
        if m:
            options.add(m.group(1))
        elif section == "subcommands":
            m = SUBCOMMAND_LINE.match(line)
            if m:
                subcommands.append(m.group(1))
    options.discard("--help")
    return options, subcommands


commands = {}  # "bench leds" -> its options


def discover(path):
    options, subs = parse_help(help_text(path))
    if path:
        commands[" ".join(path)] = options
    for sub in subs:
        discover(path + [sub])


discover([])
if not commands:
    problems.append("'lightstage --help' lists no subcommands")

# --- 2. What docs/cli.md says --------------------------------------------------------------------
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
OPTION = re.compile(r"(?<![\w-])--[A-Za-z0-9][A-Za-z0-9_-]*")
MENTION = re.compile(r"\blightstage\s+([a-z][a-z0-9-]*)(?:\s+([a-z][a-z0-9-]*))?")


def command_of(words):
    """The command a 'lightstage WORD [WORD]' mention names, or None."""
    first, second = words
    if first and second and f"{first} {second}" in commands:
        return f"{first} {second}"
    return first if first in commands else None


doc_path = os.path.join(root, "docs", "cli.md")
documented = {name: set() for name in commands}
sections = set()
named_elsewhere = []  # (line number, command, option): options attributed by a mention
current, level = None, 0
with open(doc_path, encoding="utf-8") as doc:
    for number, line in enumerate(doc, 1):
        heading = HEADING.match(line)
        if heading and not line.startswith("    "):
            text = heading.group(2).replace("`", "").strip()
            if text.startswith("lightstage "):
                name = " ".join(text.split()[1:])
                if name not in commands:
                    problems.append(f"docs/cli.md:{number}: section '{text}': no such command "
                                    "in --help")
                    current = None
                else:
                    current, level = name, len(heading.group(1))
                    sections.add(name)
                continue
            if current is not None and len(heading.group(1)) <= level:
                current = None
        # Options belong to the section's command, or to the command a mention on the line names.
        owner, position = current, 0
        marks = [(m.start(), command_of(m.groups())) for m in MENTION.finditer(line)]
        for option in OPTION.finditer(line):
            for start, named in marks:
                if start < option.start() and named is not None:
                    owner = named
            if owner is None:
                continue
            flag = option.group(0)
            if flag == "--help":
                continue
            if flag not in commands[owner]:
                problems.append(f"docs/cli.md:{number}: '{flag}' is not an option of "
                                f"'lightstage {owner}' (its --help does not list it)")
            elif owner == current:
                documented[owner].add(flag)

for name in sorted(commands):
    if name not in sections:
        problems.append(f"docs/cli.md: no section 'lightstage {name}'")
        continue
    for flag in sorted(commands[name] - documented[name]):
        problems.append(f"docs/cli.md: 'lightstage {name}' section lacks {flag} "
                        "(listed by its --help)")

# --- 3. Links in README.md and docs/ -------------------------------------------------------------
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def strip_code(text):
    text = re.sub(r"^(```|~~~).*?^\1[^\n]*$", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def slug(heading):
    text = heading.strip().lower().replace("`", "")
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    found, seen, fenced = set(), {}, False
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("```") or line.startswith("~~~"):
                fenced = not fenced
            m = None if fenced else HEADING.match(line)
            if m:
                s = slug(m.group(2))
                n = seen.get(s, 0)
                seen[s] = n + 1
                found.add(s if n == 0 else f"{s}-{n}")
    return found


pages = [os.path.join(root, "README.md")]
for folder, _, files in os.walk(os.path.join(root, "docs")):
    pages += [os.path.join(folder, f) for f in sorted(files) if f.endswith(".md")]
links = 0
for page in pages:
    with open(page, encoding="utf-8") as f:
        text = strip_code(f.read())
    where = os.path.relpath(page, root)
    for m in LINK.finditer(text):
        target = m.group(1)
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
            continue
        links += 1
        path, _, anchor = target.partition("#")
        file = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
        if not file.startswith(root + os.sep) or not os.path.exists(file):
            problems.append(f"{where}: link '{target}': no file {os.path.relpath(file, root)}")
        elif anchor and file.endswith(".md") and anchor not in anchors(file):
            problems.append(f"{where}: link '{target}': no heading #{anchor} in "
                            f"{os.path.relpath(file, root)}")

for problem in problems:
    print("check_cli_doc:", problem)
options = sum(len(o) for o in commands.values())
print(f"check_cli_doc: {len(commands)} commands, {options} options against docs/cli.md; "
      f"{links} relative links in {len(pages)} pages: "
      f"{'OK' if not problems else f'{len(problems)} problem(s)'}")
sys.exit(1 if problems else 0)
PY
