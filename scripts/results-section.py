#!/usr/bin/env python3
"""Writes one section of docs/RESULTS.md and leaves every other byte of the file as it was.

Every section of docs/RESULTS.md lies between two marker lines that name it and its owner:

    <!-- NAME:begin, written by scripts/SCRIPT -->     a section one script writes
    <!-- NAME:begin, by hand -->                       a section measured and written by hand
    ...
    <!-- NAME:end -->

Only the owner named in a section's begin marker writes it, and no script writes a section
marked by hand. Every writer of docs/RESULTS.md goes through this script:

    python3 scripts/results-section.py write FILE NAME OWNER [BODY]
        Puts BODY (a file, or standard input when omitted or "-"; the section's text without
        its markers, kept to the byte) between NAME's markers, written for OWNER (the writing
        script's path, e.g. scripts/bench-peers.sh).
        The section is replaced where it is, or appended after a blank line when FILE has no
        section NAME (FILE is created when missing). Refused, with FILE left as it was: a
        section NAME that another owner or a person writes, a BODY holding a marker line, and a
        FILE whose markers are malformed, unpaired, nested or repeated.
    python3 scripts/results-section.py check FILE
        Lists every section and its owner; exit status 1 when a marker is wrong or a line that
        is not blank lies outside every section.
    python3 scripts/results-section.py --self-test
        Tests the above on made-up text and on a copy of docs/RESULTS.md (when there is one):
        each script's section replaced and written back, every other byte compared.

Exit status: 0 done, 1 refused (the message says why), 2 bad arguments.
"""

import os
import re
import shutil
import sys
import tempfile

BEGIN = re.compile(r"<!-- ([a-z0-9][a-z0-9-]*):begin, (?:written by (\S+)|(by hand)) -->")
END = re.compile(r"<!-- ([a-z0-9][a-z0-9-]*):end -->")
# Anything that looks like a marker must be one exactly: an old or mistyped marker is refused
# rather than read as text (a writer would otherwise append a second copy of its section).
MARKERISH = re.compile(r"\s*<!--\s*[A-Za-z0-9_-]+\s*:\s*(begin|end)\b")
BY_HAND = "by hand"


class Refused(Exception):
    pass


class Section:
    def __init__(self, name, owner, begin, end):
        self.name, self.owner, self.begin, self.end = name, owner, begin, end


def sections(lines, path):
    """The sections of a file's lines (each kept with its line ending), checked."""
    found, open_ = [], None
    for i, raw in enumerate(lines):
        line = raw.rstrip("\r\n")
        b, e = BEGIN.fullmatch(line), END.fullmatch(line)
        where = f"{path}:{i + 1}"
        if b:
            if open_:
                raise Refused(f"{where}: section {b[1]} begins inside section {open_.name}")
            open_ = Section(b[1], b[2] or BY_HAND, i, None)
        elif e:
            if not open_ or open_.name != e[1]:
                raise Refused(f"{where}: {e[1]}:end without its begin")
            open_.end = i
            found.append(open_)
            open_ = None
        elif MARKERISH.match(line):
            raise Refused(f"{where}: malformed marker {line.strip()!r} (see --help for the form)")
    if open_:
        raise Refused(f"{path}:{open_.begin + 1}: section {open_.name} has no end marker")
    names = [s.name for s in found]
    for n in names:
        if names.count(n) > 1:
            raise Refused(f"{path}: section {n} appears {names.count(n)} times")
    return found


def read(path):
    try:
        with open(path, encoding="utf-8", newline="") as f:
            return f.read()
    except FileNotFoundError:
        return ""


def replaced(text, name, owner, body, path="FILE"):
    """TEXT with section NAME holding BODY for OWNER; every other byte of TEXT kept."""
    if owner == BY_HAND or not owner or any(c.isspace() for c in owner):
        raise Refused(f"owner {owner!r}: give the writing script's path (a section by hand is edited by hand)")
    if body and not body.endswith("\n"):
        body += "\n"
    for line in body.splitlines():
        if BEGIN.fullmatch(line) or END.fullmatch(line) or MARKERISH.match(line):
            raise Refused(f"the text for section {name} holds a marker line: {line.strip()!r}")
    lines = text.splitlines(keepends=True)
    old = {s.name: s for s in sections(lines, path)}
    # The body as given, to the byte (a final newline added when it has none).
    new = [f"<!-- {name}:begin, written by {owner} -->\n", body, f"<!-- {name}:end -->\n"]
    if name in old:
        s = old[name]
        if s.owner != owner:
            raise Refused(f"{path}:{s.begin + 1}: section {name} is written {'by hand' if s.owner == BY_HAND else 'by ' + s.owner}, not by {owner}")
        # The end marker's own line ending is kept (the file's last line may have none).
        ending = lines[s.end][len(lines[s.end].rstrip("\r\n")):]
        new[-1] = new[-1][:-1] + ending
        return "".join(lines[: s.begin] + new + lines[s.end + 1:])
    if not text:
        sep = ""
    elif text.endswith("\n\n"):
        sep = ""
    elif text.endswith("\n"):
        sep = "\n"
    else:
        sep = "\n\n"
    return text + sep + "".join(new)


def write(path, name, owner, body):
    text = read(path)
    out = replaced(text, name, owner, body, path)
    if out == text:
        return
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".results-section.", dir=directory)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.write(out)
        if os.path.exists(path):
            shutil.copymode(path, tmp)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def check(path):
    text = read(path)
    lines = text.splitlines(keepends=True)
    found = sections(lines, path)
    inside = set()
    for s in found:
        inside.update(range(s.begin, s.end + 1))
    stray = [i + 1 for i, l in enumerate(lines) if i not in inside and l.strip()]
    for s in found:
        heading = next((l.strip() for l in lines[s.begin:s.end] if l.startswith("#")), "")
        print(f"{s.name}\t{s.owner}\t{heading}")
    if stray:
        shown = ", ".join(map(str, stray[:10])) + (" ..." if len(stray) > 10 else "")
        raise Refused(f"{path}: {len(stray)} lines outside every section (lines {shown})")


def self_test():
    checks = 0

    def expect(cond, what):
        nonlocal checks
        if not cond:
            raise AssertionError(what)
        checks += 1

    def refused(f, *a):
        try:
            f(*a)
        except Refused:
            return True
        return False

    doc = (
        "<!-- preface:begin, by hand -->\n# Results\n\nIntro.\n<!-- preface:end -->\n\n"
        "<!-- a:begin, written by scripts/a.sh -->\n## A\n\nold a\n<!-- a:end -->\n\n"
        "<!-- notes:begin, by hand -->\n## Notes\n<!-- notes:end -->\n\n"
        "<!-- b:begin, written by scripts/b.sh -->\n## B\nold b\n<!-- b:end -->\n"
    )
    out = replaced(doc, "a", "scripts/a.sh", "## A\n\nnew a\nsecond line\n")
    head, tail = doc.split("<!-- a:begin")[0], doc.split("<!-- a:end -->\n")[1]
    expect(out.startswith(head) and out.endswith(tail), "bytes around a replaced section kept")
    expect("new a\nsecond line\n<!-- a:end -->" in out and "old a" not in out, "section replaced")
    expect(replaced(out, "a", "scripts/a.sh", "## A\n\nnew a\nsecond line\n") == out, "rewrite is a no-op")
    expect(replaced(out, "a", "scripts/a.sh", "## A\n\nold a\n") == doc, "writing the old text back restores the file")
    appended = replaced(doc, "c", "scripts/c.sh", "## C\n")
    expect(appended == doc + "\n<!-- c:begin, written by scripts/c.sh -->\n## C\n<!-- c:end -->\n", "missing section appended")
    expect(replaced("", "c", "scripts/c.sh", "x") == "<!-- c:begin, written by scripts/c.sh -->\nx\n<!-- c:end -->\n", "new file")
    expect(replaced("text", "c", "s", "x").startswith("text\n\n<!-- c:begin"), "a last line without a newline kept")
    no_eol = doc.rstrip("\n")
    expect(replaced(no_eol, "b", "scripts/b.sh", "## B\nold b\n") == no_eol, "a last marker without a newline kept")
    expect(refused(replaced, doc, "notes", "scripts/a.sh", "x"), "a section by hand is not written")
    expect(refused(replaced, doc, "b", "scripts/a.sh", "x"), "another script's section is not written")
    expect(refused(replaced, doc, "new", BY_HAND, "x"), "no script writes as a person")
    expect(refused(replaced, doc, "a", "scripts/a.sh", "x\n<!-- b:end -->\n"), "a body with a marker is refused")
    expect(refused(replaced, doc.replace("<!-- a:end -->\n", ""), "b", "scripts/b.sh", "x"), "an unpaired marker is refused")
    expect(refused(replaced, doc + "<!-- a:begin, written by scripts/a.sh -->\n<!-- a:end -->\n", "b", "scripts/b.sh", "x"), "a repeated section is refused")
    expect(refused(replaced, doc.replace("<!-- b:begin, written by scripts/b.sh -->", "<!-- b:begin -->"), "b", "scripts/b.sh", "x"), "an old-style marker is refused")

    # The real document, on a copy: every script's section replaced, then written back.
    here = os.path.dirname(os.path.abspath(__file__))
    results = os.path.normpath(os.path.join(here, "..", "docs", "RESULTS.md"))
    real = 0
    if os.path.exists(results):
        original = read(results)
        with tempfile.TemporaryDirectory() as d:
            copy = os.path.join(d, "RESULTS.md")
            shutil.copyfile(results, copy)
            lines = original.splitlines(keepends=True)
            for s in sections(lines, results):
                if s.owner == BY_HAND:
                    continue
                before, after = "".join(lines[: s.begin]), "".join(lines[s.end + 1:])
                body = "".join(lines[s.begin + 1: s.end])
                write(copy, s.name, s.owner, f"## {s.name}, replaced by the self-test\n")
                text = read(copy)
                expect(text.startswith(before) and text.endswith(after), f"{s.name}: every other byte of RESULTS.md kept")
                write(copy, s.name, s.owner, body)
                expect(read(copy) == original, f"{s.name}: written back, RESULTS.md is byte-identical")
                real += 1
    print(f"results-section: self-test passed ({checks} checks; {real} sections of docs/RESULTS.md replaced and restored)")


def main(argv):
    try:
        if argv == ["--self-test"]:
            self_test()
        elif len(argv) in (4, 5) and argv[0] == "write":
            body_path = argv[4] if len(argv) == 5 else "-"
            if body_path == "-":
                body = sys.stdin.read()
            else:
                with open(body_path, encoding="utf-8") as f:
                    body = f.read()
            write(argv[1], argv[2], argv[3], body)
        elif len(argv) == 2 and argv[0] == "check":
            check(argv[1])
        elif argv in (["--help"], ["-h"]):
            print(__doc__.strip())
        else:
            print(__doc__.strip(), file=sys.stderr)
            return 2
    except Refused as e:
        print(f"results-section: {e}; the file is left as it was", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
