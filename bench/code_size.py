"""Lines of code, function lengths and the tests' private imports of the warp core.

    python -m bench.code_size [package dir] [tests dir]

Counts what issue 16 measures, two ways. A line of code is a physical line
that holds some token other than a comment, a docstring or the line breaks
around them (a blank line, a comment line and every line of a docstring do not
count; a docstring is a string expression standing alone as the first
statement of a module, class or function). The issue's own figure (5,367 at
its filing) counted every line that is neither blank nor only a comment, so
docstrings too; that count is printed beside it ("with docstrings"), and it is
the one the issue's limit of 4,500 is held to (the stricter of the two). A function's length is its code lines, the
``def`` line and its decorators included. A private import is a name
``_name`` imported from the package by a test module (``from addon.warp.x
import _name``, or ``module._name`` read through an imported module).
"""
from __future__ import annotations

import ast
import io
import sys
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def docstring_lines(tree: ast.AST) -> set[int]:
    """The physical lines of every module, class and function docstring."""
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                lines.update(range(body[0].lineno, body[0].end_lineno + 1))
    return lines


def code_lines(source: str) -> set[int]:
    """The physical lines that hold code (not blank, comment or docstring)."""
    docs = docstring_lines(ast.parse(source))
    lines: set[int] = set()
    skip = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
            tokenize.ENCODING, tokenize.ENDMARKER}
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type in skip:
            continue
        for line in range(tok.start[0], tok.end[0] + 1):
            if line not in docs:
                lines.add(line)
    return lines


def function_lengths(source: str, code: set[int]):
    """(name, first line, code lines) of every function, nested ones on their own."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            first = min([node.lineno] + [d.lineno for d in node.decorator_list])
            span = range(first, node.end_lineno + 1)
            out.append((node.name, node.lineno, sum(1 for i in span if i in code)))
    return out


def private_imports(tests: Path, package: str = "addon.warp") -> list[tuple[str, str]]:
    """(test file, module.name) for every private name the tests take from the package."""
    found = set()
    for path in sorted(tests.rglob("*.py")):
        tree = ast.parse(path.read_text())
        aliases = {}                        # local name -> module it stands for
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(package):
                for a in node.names:
                    if a.name.startswith("_") and not a.name.startswith("__"):
                        found.add((path.name, f"{node.module}.{a.name}"))
                    else:
                        aliases[a.asname or a.name] = f"{node.module}.{a.name}"
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith(package):
                        aliases[a.asname or a.name] = a.name
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
                base = node.value
                if isinstance(base, ast.Name) and base.id in aliases:
                    found.add((path.name, f"{aliases[base.id]}.{node.attr}"))
    return sorted(found)


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    package = Path(argv[0]) if argv else ROOT / "addon" / "warp"
    tests = Path(argv[1]) if len(argv) > 1 else ROOT / "tests" / "warp"
    total, with_docs, longest = 0, 0, []
    per_file = []
    for path in sorted(package.rglob("*.py")):
        source = path.read_text()
        code = code_lines(source)
        total += len(code)
        plain = sum(1 for line in source.splitlines() if line.strip() and not line.lstrip().startswith("#"))
        with_docs += plain
        per_file.append((len(code), plain, path.relative_to(package)))
        longest += [(n, f"{path.relative_to(package)}:{line} {name}") for name, line, n in function_lengths(source, code)]
    print("  code  with docstrings")
    for n, d, name in sorted(per_file, reverse=True):
        print(f"{n:6d} {d:6d}  {name}")
    where = package.relative_to(ROOT) if package.is_relative_to(ROOT) else package
    print(f"{total:6d} {with_docs:6d}  lines of code in {where} (without, with docstrings)")
    longest.sort(reverse=True)
    print("longest functions (code lines):")
    for n, where in longest[:8]:
        print(f"{n:6d}  {where}")
    private = private_imports(tests)
    names = sorted({name for _, name in private})
    print(f"{len(names)} private names imported by the tests:")
    for name in names:
        print(f"        {name}  ({', '.join(sorted(f for f, n in private if n == name))})")


if __name__ == "__main__":
    main()
