"""Where in a TOML file's text a key is written twice: the TOML parser refuses such a file with
a line and a column; this names the key as the rest of forcecal does (``actuator.pole_area``,
``forces[0].gap``)."""

from __future__ import annotations

import ast
import re

__all__ = ["duplicated_key"]

_AT = re.compile(r"\(at line (\d+), column (\d+)\)")
_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_ASSIGN = re.compile(r"^\s*([A-Za-z0-9_.\"' -]+?)\s*=")
_STRING = re.compile(r"\"(?:[^\"\\]|\\.)*\"|'[^']*'")


def _table(lines: list[str], line: int) -> str:
    """The dotted path of the table that holds line ``line`` (1-based): ``gauges[1]``."""
    for k in range(line - 1, -1, -1):
        match = _HEADER.match(lines[k])
        if match is None:
            continue
        brackets, name = match.group(1), match.group(2).replace(" ", "")
        if brackets == "[[":
            index = sum(1 for text in lines[:k] if (m := _HEADER.match(text)) is not None
                        and m.group(1) == "[[" and m.group(2).replace(" ", "") == name)
            return f"{name}[{index}]"
        return name
    return ""


def _inline_path(text: str) -> str:
    """The path, below its table, of the inline table open at the end of ``text`` (the file
    from its table's header to the duplicate): ``forces[0]`` or ``s2``."""
    text = _STRING.sub('""', text)
    path: list[str] = []
    stack: list[list[int]] = []           # per open [ or {: [kind, entries seen]
    key = ""
    for token in re.finditer(r"([A-Za-z0-9_.-]+)\s*=|[\[\]{},]", text):
        t = token.group(0)
        if token.group(1) is not None:
            key = token.group(1)
        elif t in "[{":
            if stack and stack[-1][0] == ord("["):
                path.append(f"[{stack[-1][1]}]")
            else:
                path.append(("." if path else "") + key)
            stack.append([ord(t), 0])
        elif t in "]}" and stack:
            stack.pop()
            path.pop()
            if stack and stack[-1][0] == ord("["):
                stack[-1][1] += 1
    return "".join(path)


def duplicated_key(text: str, message: str) -> str | None:
    """The dotted key a TOML parser's message says is written twice, or None when the message
    is of another fault.

    Parameters
    ----------
    text : str
        The file.
    message : str
        The parser's message (``Cannot overwrite a value (at line 28, column 19)``).

    Returns
    -------
    str or None
    """
    declared = re.match(r"Cannot declare (\(.*?\)) twice", message)
    if declared is not None:
        return ".".join(ast.literal_eval(declared.group(1)))
    at = _AT.search(message)
    if at is None or not message.startswith(("Cannot overwrite a value",
                                             "Duplicate inline table key")):
        return None
    lines = text.splitlines()
    line, column = int(at.group(1)), int(at.group(2))
    table = _table(lines, line)
    start = next((k + 1 for k in range(line - 1, -1, -1) if _HEADER.match(lines[k])), 0)
    before = "\n".join([*lines[start:line - 1], lines[line - 1][:column - 1]])
    inline = re.match(r"Duplicate inline table key '([^']*)'", message)
    if inline is not None:
        key = inline.group(1)
        inner = _inline_path(before)
    else:
        assign = _ASSIGN.match(lines[line - 1])
        if assign is None:
            return None
        key = assign.group(1).replace('"', "").replace("'", "").replace(" ", "")
        inner = _inline_path(before.rsplit("\n", 1)[0] if "\n" in before else "")
    parts = [p for p in (table, inner.lstrip("."), key) if p]
    return ".".join(parts).replace(".[", "[")
