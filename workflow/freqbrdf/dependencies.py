"""Which library modules a rule's script runs: its freqbrdf imports, followed transitively.

The rules declare these source files as inputs, so that editing a module
reruns exactly the rules whose scripts use it (`rules/common.smk`,
``library``). Derived from the code, not listed by hand: a hand-kept list
drifts, and a stale result is silent.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

__all__ = ["script_modules"]

PACKAGE = "freqbrdf"


def _imported(tree: ast.AST, in_package: bool) -> set[str]:
    """Top-level freqbrdf modules named by the imports of one file (absolute, and relative inside the package)."""
    out: set[str] = set()
    for node in ast.walk(tree):  # imports inside functions count too
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == PACKAGE and len(parts) > 1:
                    out.add(parts[1])
        elif isinstance(node, ast.ImportFrom):
            relative = in_package and node.level == 1
            if node.level == 0 and node.module and node.module.split(".")[0] == PACKAGE:
                parts = node.module.split(".")
                out |= {parts[1]} if len(parts) > 1 else {alias.name for alias in node.names}
            elif relative:
                out |= {node.module.split(".")[0]} if node.module else {alias.name for alias in node.names}
    return out


@functools.cache
def _package_imports(source: str, stamp: tuple[int, int]) -> frozenset[str]:
    """`_imported` of one package module, parsed once per process and version (``stamp``:
    modification time and size): every rule's `script_modules` walks the same modules, and
    parsing them anew for each made most of a dry run's time."""
    return frozenset(_imported(ast.parse(Path(source).read_text(), filename=source), in_package=True))


def script_modules(script: str | Path, package_dir: str | Path) -> list[str]:
    """Names of the freqbrdf modules a script imports, directly or through each other.

    Parameters
    ----------
    script : str or Path
        A Python file outside the package (a rule's entry script).
    package_dir : str or Path
        The ``freqbrdf`` package directory.

    Returns
    -------
    list of str
        Sorted module names (file stems), ``__init__`` included: importing
        any module of a package runs its ``__init__``.
    """
    script, package_dir = Path(script), Path(package_dir)
    if not script.is_file():
        raise FileNotFoundError(f"{script}: rule script not found")
    todo = _imported(ast.parse(script.read_text(), filename=str(script)), in_package=False)
    seen = {"__init__"}
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        source = package_dir / f"{name}.py"
        if not source.is_file():
            raise FileNotFoundError(f"{script} imports {PACKAGE}.{name}, but {source} does not exist")
        seen.add(name)
        stat = source.stat()
        todo |= _package_imports(str(source), (stat.st_mtime_ns, stat.st_size))
    return sorted(seen)
