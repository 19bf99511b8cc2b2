"""Which library files a rule's script runs: its freqbrdf imports, followed transitively.

The rules declare these source files as inputs, so that editing a module
reruns exactly the rules whose scripts use it (`rules/common.smk`,
``library``). Derived from the code, not listed by hand: a hand-kept list
drifts, and a stale result is silent.

Importing ``freqbrdf.a.b`` runs ``freqbrdf/__init__.py``, ``a/__init__.py`` and
``a/b.py``; ``from freqbrdf.a import b`` imports ``b`` as a module when it is
one (a file or a subpackage), otherwise it is a name of ``a/__init__.py``.
Relative imports are resolved against the importing file's package, at any level.
The same parse draws the package's import graph (`package_imports`), whose floors
``tests/test_floors.py`` checks (docs/modules.md, "Floors").
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

__all__ = ["package_imports", "script_modules"]

PACKAGE = "freqbrdf"


def _module_file(package_dir: Path, dotted: str) -> Path | None:
    """Source file of module ``dotted`` (relative to the package: ``"a.b"``; ``""`` is the
    package itself): ``a/b.py`` or ``a/b/__init__.py``; None when neither exists."""
    base = package_dir.joinpath(*dotted.split(".")) if dotted else package_dir
    for candidate in (base / "__init__.py", base.with_suffix(".py") if dotted else None):
        if candidate is not None and candidate.is_file():
            return candidate
    return None


def _with_parents(dotted: str) -> set[str]:
    """``"a.b.c"`` -> {"", "a", "a.b", "a.b.c"}: importing a module runs every enclosing package."""
    parts = dotted.split(".") if dotted else []
    return {".".join(parts[:i]) for i in range(len(parts) + 1)}


def _imported(tree: ast.AST, package_dir: Path, here: str | None) -> set[str]:
    """Package-relative dotted names of the freqbrdf modules one file's imports run.

    ``here`` is the dotted name of the package the file lies in (``""`` for the top level), or
    None for a file outside the package, whose relative imports cannot reach it."""
    out: set[str] = set()
    for node in ast.walk(tree):  # imports inside functions count too
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == PACKAGE:
                    out |= _with_parents(".".join(parts[1:]))
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                parts = (node.module or "").split(".")
                if parts[0] != PACKAGE:
                    continue
                base = ".".join(parts[1:])
            elif here is None:
                continue
            else:
                up = here.split(".") if here else []
                if node.level - 1 > len(up):
                    raise ImportError(f"relative import beyond the {PACKAGE} package in {here or PACKAGE}")
                up = up[: len(up) - (node.level - 1)]
                base = ".".join(up + ([node.module] if node.module else []))
            out |= _with_parents(base)
            for alias in node.names:
                child = f"{base}.{alias.name}" if base else alias.name
                if _module_file(package_dir, child) is not None:
                    out.add(child)
    return out


@functools.cache
def _package_imports(source: str, here: str, package_dir: str, stamp: tuple[int, int]) -> frozenset[str]:
    """`_imported` of one package module, parsed once per process and version (``stamp``:
    modification time and size): every rule's `script_modules` walks the same modules, and
    parsing them anew for each made most of a dry run's time."""
    tree = ast.parse(Path(source).read_text(), filename=source)
    return frozenset(_imported(tree, Path(package_dir), here))


def script_modules(script: str | Path, package_dir: str | Path) -> list[str]:
    """Source files of the freqbrdf modules a script imports, directly or through each other.

    Parameters
    ----------
    script : str or Path
        A Python file outside the package (a rule's entry script).
    package_dir : str or Path
        The ``freqbrdf`` package directory.

    Returns
    -------
    list of str
        Sorted paths relative to ``package_dir`` (``"estimate/light.py"``), every enclosing
        package's ``__init__.py`` included: importing a module runs them.
    """
    script, package_dir = Path(script), Path(package_dir)
    if not script.is_file():
        raise FileNotFoundError(f"{script}: rule script not found")
    todo = _imported(ast.parse(script.read_text(), filename=str(script)), package_dir, None) | {""}
    seen: dict[str, Path] = {}
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        source = _module_file(package_dir, name)
        if source is None:
            missing = f"{PACKAGE}.{name}" if name else PACKAGE
            raise FileNotFoundError(f"{script} imports {missing}, but {package_dir / name.replace('.', '/')}.py does not exist")
        seen[name] = source
        here = name if source.name == "__init__.py" else name.rpartition(".")[0]
        stat = source.stat()
        todo |= _package_imports(str(source), here, str(package_dir), (stat.st_mtime_ns, stat.st_size))
    return sorted(str(path.relative_to(package_dir)) for path in seen.values())


def package_imports(package_dir: str | Path) -> dict[str, frozenset[str]]:
    """Every module of the package and the package modules it imports, function-local imports included.

    Parameters
    ----------
    package_dir : str or Path
        The ``freqbrdf`` package directory.

    Returns
    -------
    dict of str to frozenset of str
        Dotted names relative to the package (``"estimate.light"``; ``""`` is the package
        itself), each with what its own imports run: the enclosing packages of an imported
        module included, transitive imports not.
    """
    package_dir = Path(package_dir)
    graph = {}
    for source in sorted(package_dir.rglob("*.py")):
        parts = source.relative_to(package_dir).with_suffix("").parts
        here = ".".join(parts[:-1])
        name = here if parts[-1] == "__init__" else ".".join(parts)
        stat = source.stat()
        graph[name] = _package_imports(str(source), here, str(package_dir), (stat.st_mtime_ns, stat.st_size))
    return graph
