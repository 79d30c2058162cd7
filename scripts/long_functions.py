#!/usr/bin/env python3
"""Lists C++ functions longer than a limit (lines from the signature's line to the closing brace).

Usage: scripts/long_functions.py [--max N] [--tests] [PATH ...]
  PATH      files or folders (default: core store server worker cli)
  --max N   report functions longer than N lines (default 120); exit 1 if any
  --tests   include *_test.cc and test helpers (skipped by default)

A small brace matcher, not a parser: comments, string and character literals are blanked out,
then every `{` that opens a function body (a `)` before it, possibly followed by qualifiers,
`override`, `-> T` or a constructor's initialiser list, and not a control statement, a lambda
or an initialiser) is matched with its `}`. Lambdas and local classes count towards the
function around them, which is what a reader has to take in. Used by .ci/run so that the
layout rule "no function over ~120 lines" (issue 9) stays true.
"""
import argparse
import os
import re
import sys

CONTROL = re.compile(r"\b(if|for|while|switch|catch|do|else|try)\s*$")


def blank_comments_and_strings(text):
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
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text.startswith('R"', i):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if m:
                end = text.find(")" + m.group(1) + '"', i)
                end = n if end < 0 else end + len(m.group(1)) + 2
                out.append('""' + re.sub(r"[^\n]", " ", text[i + 2:end]))
                i = end
            else:
                out.append(c)
                i += 1
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(c + " " * (j - i - 1) + (c if j < n else ""))
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def is_function_body(head):
    """`head` is the code between the previous ; { } and this {."""
    h = head.strip()
    if not h or h.endswith("=") or h.endswith(",") or h.endswith("(") or h.endswith("return"):
        return False
    if re.search(r"\b(namespace|class|struct|union|enum)\b[^()]*$", h):
        return False
    # Strip trailing qualifiers: const, noexcept, override, final, -> type, initialiser lists.
    h2 = re.sub(r"\s*(const|noexcept|override|final|mutable)\s*$", "", h)
    while h2 != h:
        h, h2 = h2, re.sub(r"\s*(const|noexcept|override|final|mutable)\s*$", "", h2)
    if ")" not in h:
        return False
    # Find the parameter list: the last top-level (...) group that is followed by nothing but
    # qualifiers / trailing return / initialiser list.
    depth = 0
    for k in range(len(h) - 1, -1, -1):
        if h[k] == ")":
            depth += 1
        elif h[k] == "(":
            depth -= 1
            if depth == 0:
                before = h[:k].rstrip()
                if CONTROL.search(before) or before.endswith("]") or before.endswith(">]"):
                    return False
                if re.search(r"\]\s*$", before):  # lambda
                    return False
                # A name must precede the parameter list.
                return bool(re.search(r"[\w>~=\]\)]\s*$", before)) and not re.search(
                    r"(\[[^\]]*\]\s*)$", before)
    return False


def functions(path):
    text = open(path, encoding="utf-8", errors="replace").read()
    code = blank_comments_and_strings(text)
    line_of = []
    line = 1
    for ch in code:
        line_of.append(line)
        if ch == "\n":
            line += 1
    stack = []  # (kind, start_index, name)
    last_break = 0
    for i, ch in enumerate(code):
        if ch == "{":
            head = code[last_break:i]
            in_function = any(kind == "fn" for kind, _, _ in stack)
            if not in_function and is_function_body(head):
                name_match = re.search(r"([\w:~<>]+)\s*\((?:[^()]|\([^()]*\))*\)[^()]*$", head)
                name = name_match.group(1) if name_match else "?"
                # Start at the first non-blank line of the head (the signature).
                start = last_break + (len(head) - len(head.lstrip()))
                stack.append(("fn", start, name))
            else:
                stack.append(("block", i, ""))
            last_break = i + 1
        elif ch == "}":
            if stack:
                kind, start, name = stack.pop()
                if kind == "fn":
                    yield name, line_of[start], line_of[i]
            last_break = i + 1
        elif ch == ";":
            last_break = i + 1


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("paths", nargs="*", default=["core", "store", "server", "worker", "cli"])
    parser.add_argument("--max", type=int, default=120)
    parser.add_argument("--tests", action="store_true")
    args = parser.parse_args()
    files = []
    for p in args.paths:
        if os.path.isdir(p):
            for root, _, names in os.walk(p):
                files += [os.path.join(root, f) for f in names if f.endswith((".cc", ".h"))]
        else:
            files.append(p)
    found = []
    for f in sorted(files):
        base = os.path.basename(f)
        if not args.tests and ("_test" in base or "test_util" in base or "test_client" in base):
            continue
        for name, first, last in functions(f):
            length = last - first + 1
            if length > args.max:
                found.append((length, f, first, name))
    for length, f, first, name in sorted(found, reverse=True):
        print(f"{f}:{first}: {name}: {length} lines")
    if found:
        print(f"{len(found)} functions longer than {args.max} lines", file=sys.stderr)
        return 1
    print(f"no function longer than {args.max} lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())
