"""The command line is one package, agnav_host.cli, that owns every command and argument type; no other module
of agnav_host imports it (the library is usable without the CLI, and a command never hides in a library)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import agnav_host
from agnav_host import cli

PACKAGE = Path(agnav_host.__file__).parent
CLI = "agnav_host.cli"


def _module_name(path: Path, root: Path = PACKAGE) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(source: str, module: str, is_package: bool = False) -> set[str]:
    """Every module the source of ``module`` imports, by absolute name (relative imports resolved; ``from X
    import Y`` counts X and X.Y; ``importlib.import_module("X")`` counts X)."""
    package = module.split(".") if is_package else module.split(".")[:-1]
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            mod = ".".join([*base, *([node.module] if node.module else [])])
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) == "import_module"
              and node.args and isinstance(node.args[0], ast.Constant)):
            out.add(str(node.args[0].value))
    return out


def cli_imports(source: str, module: str, is_package: bool = False) -> list[str]:
    return sorted(m for m in imported_modules(source, module, is_package) if m == CLI or m.startswith(CLI + "."))


def library_modules_importing_the_cli(root: Path) -> dict[str, list[str]]:
    """module -> the CLI modules it imports, for every module of the package at ``root`` outside the CLI."""
    out = {}
    for p in sorted(root.rglob("*.py")):
        name = _module_name(p, root)
        if name == CLI or name.startswith(CLI + "."):
            continue
        found = cli_imports(p.read_text(encoding="utf-8"), name, p.name == "__init__.py")
        if found:
            out[name] = found
    return out


def test_no_library_module_imports_the_cli():
    assert len(list(PACKAGE.rglob("*.py"))) > 50  # the walk finds the library
    assert library_modules_importing_the_cli(PACKAGE) == {}


@pytest.mark.parametrize("source", ["from ..cli import main", "from .. import cli", "import agnav_host.cli.argv",
                                    "from agnav_host.cli.outputs import OutputError", "from ..cli.argtypes import DAY_S",
                                    "import importlib\nimportlib.import_module('agnav_host.cli.sim')"])
def test_every_form_of_importing_the_cli_is_seen(source):
    assert cli_imports(source, "agnav_host.link.commands")


def test_running_the_command_or_a_relative_import_elsewhere_is_not_importing_the_cli():
    source = "from ..link import config\nfrom . import cli_tools\nimport subprocess\nARGS = ['-m', 'agnav_host.cli']\n"
    assert cli_imports(source, "agnav_host.sil.robot_path") == []
    assert cli_imports("from .cli import x", "agnav_host.link", is_package=True) == []  # agnav_host.link.cli


def test_every_command_is_defined_in_the_cli_package():
    cli.build_parser()
    assert {"scenarios", "sim", "rows", "planners", "bench", "plan", "run", "param", "sil", "faults"} <= set(cli.SUBCOMMANDS)
    for name, sub in cli.SUBCOMMANDS.items():
        assert sub.handler.__module__.startswith(CLI + "."), (name, sub.handler.__module__)
