#!/usr/bin/env python3
"""Lists C++ functions longer than a limit and files longer than a limit (issue 16: no library
function over about 150 lines, no library file over about 800, without a reason in a comment).

    python3 scripts/function_sizes.py [--function-lines 150] [--file-lines 800] DIR_OR_FILE...

A function is a brace block whose opening follows a parameter list ')' (optionally const,
noexcept, override, a trailing return type or a constructor's initialiser list) at namespace or
class level; lambdas and control blocks inside a function count towards it. Strings, character
literals and comments are skipped. A heuristic, not a parser: it reads the text as written.
A long function whose comment directly above its signature gives the reason (says "on
purpose" or "reason") is still listed, marked "reason given": the others are what to cut.
Exit status 0 always; the report is the output.
"""
import argparse
import os
import re
import sys

EXTS = (".cpp", ".cc", ".h", ".hpp")


def strip(text):
    """The text with comments, strings and character literals blanked (newlines kept)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("".join(ch if ch == "\n" else " " for ch in text[i:j]))
            i = j
        elif c == 'R' and text.startswith('R"', i):
            m = re.match(r'R"([^(]*)\(', text[i:])
            if not m:
                out.append(c)
                i += 1
                continue
            end = ")" + m.group(1) + '"'
            j = text.find(end, i + m.end())
            j = n if j < 0 else j + len(end)
            out.append("".join(ch if ch == "\n" else " " for ch in text[i:j]))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(" " * (min(j + 1, n) - i))
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


HEAD = re.compile(r"\)\s*(const\s*)?(noexcept(\([^)]*\))?\s*)?(override\s*)?(final\s*)?(->\s*[\w:<>,\s*&]+)?\s*$")
INIT = re.compile(r"\)\s*:\s*[\w:]+\s*[({]")
SCOPE = re.compile(r"\b(namespace|class|struct|union|enum)\b[^;{}()]*$")


def functions(text):
    """(name, first line, last line, signature line) of every function body in `text`."""
    s = strip(text)
    stack = []  # per open brace: 'scope', 'function' or 'block'
    found = []
    start = {}
    last = 0  # where the text before the current brace begins
    for i, c in enumerate(s):
        if c == "{":
            before = s[last:i]
            inside_function = any(k == "function" for k, _ in stack)
            if inside_function:
                kind = "block"
            elif SCOPE.search(before) and not re.search(r"\)\s*$", before):
                kind = "scope"
            elif HEAD.search(before) or INIT.search(before) or re.search(r"\)\s*:[^;{}]*$", before):
                kind = "function"
            else:
                kind = "block"
            stack.append((kind, i))
            if kind == "function":
                m = re.search(r"([~\w:]+)\s*\([^;{}]*$", before, re.S)
                sig = s.count("\n", 0, last + m.start(1)) + 1 if m else s.count("\n", 0, i) + 1
                start[i] = (m.group(1) if m else "?", s.count("\n", 0, i) + 1, sig)
            last = i + 1
        elif c == "}":
            if stack:
                kind, at = stack.pop()
                if kind == "function":
                    name, line, sig = start[at]
                    found.append((name, line, s.count("\n", 0, i) + 1, sig))
            last = i + 1
        elif c == ";":
            last = i + 1
    return found


def reason_above(lines, sig):
    """True when the // comment lines directly above line `sig` (1-based) give a reason."""
    k, block = sig - 2, []
    while k >= 0 and lines[k].strip().startswith("//"):
        block.append(lines[k])
        k -= 1
    return re.search(r"on purpose|reason", " ".join(block), re.I) is not None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("paths", nargs="+")
    ap.add_argument("--function-lines", type=int, default=150)
    ap.add_argument("--file-lines", type=int, default=800)
    a = ap.parse_args()
    files = []
    for p in a.paths:
        if os.path.isdir(p):
            for root, _, names in os.walk(p):
                files += [os.path.join(root, x) for x in names if x.endswith(EXTS)]
        else:
            files.append(p)
    for f in sorted(files):
        text = open(f, encoding="utf-8", errors="replace").read()
        n = text.count("\n")
        if n > a.file_lines:
            print("%s: file of %d lines (limit %d)" % (f, n, a.file_lines))
        lines = text.split("\n")
        for name, first, last, sig in functions(text):
            if last - first + 1 > a.function_lines:
                print("%s:%d: %s: %d lines (limit %d)%s" % (f, first, name, last - first + 1, a.function_lines,
                                                          "; reason given" if reason_above(lines, sig) else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
