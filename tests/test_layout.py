"""Tests of the package's layout: one direction of imports, no circles, no private names across
subpackages, few positional parameters, ``ruff format`` deciding the layout (``# fmt: skip`` only
for aligned tables), a light ``import aeromag_env`` and a public API that resolves. The contracts
themselves are in ``pyproject.toml`` (``[tool.importlinter]``)."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import aeromag_env

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("aeromag_env", "agents")
#: Most positional parameters a function takes; kernels group their arrays in NamedTuples.
MAX_PARAMETERS = 12
#: ``ruff format`` decides the layout; ``# fmt: skip`` is for aligned tables only (STYLE.md).
MAX_FMT_SKIPS = 20


def _sources() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _lint_imports(root: Path) -> subprocess.CompletedProcess[str]:
    """import-linter on the tree under ``root`` with the contracts of ``root/pyproject.toml``."""
    code = (
        "import sys; from importlinter.cli import lint_imports;"
        "sys.exit(lint_imports(no_cache=True))"
    )
    return subprocess.run(
        [sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=False
    )


def _copy_tree(tmp_path: Path) -> Path:
    for pkg in (*PACKAGES, "experiments"):
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path


def test_import_contracts_kept() -> None:
    run = _lint_imports(ROOT)
    assert run.returncode == 0, run.stdout[-3000:]
    assert "6 kept, 0 broken" in run.stdout


@pytest.mark.parametrize(
    ("module", "statement", "contract"),
    [
        # an upward import: compensation reaching into the environment
        ("aeromag_env/compensation/metrics.py", "import aeromag_env.environment.env", "files ->"),
        # agents below the jobs: the environment may not import it
        ("aeromag_env/environment/env.py", "import agents.policies.baselines", "files ->"),
        # the jobs above agents: agents may not import them
        ("agents/evaluation/episodes.py", "import aeromag_env.jobs.evaluate", "files ->"),
        # agents' rooms: the policies may not import training
        ("agents/policies/baselines.py", "import agents.training.ppo", "agents in rooms"),
        # the command line imports only the jobs
        ("aeromag_env/cli/commands.py", "import aeromag_env.flight.files", "the command line"),
        # outside the command line, only its entry points
        ("experiments/import_time.py", "import aeromag_env.cli.options", "outside the command"),
        # one experiment importing another
        ("experiments/import_time.py", "import experiments.seed_table", "no experiment"),
        # a circle between two modules of one package
        ("aeromag_env/compensation/dsp.py", "import aeromag_env.compensation.metrics", "circles"),
    ],
)
def test_import_contracts_catch_a_violation(
    tmp_path: Path, module: str, statement: str, contract: str
) -> None:
    """The contracts are not vacuous: one bad import in a copy of the tree breaks the one that
    forbids it."""
    tree = _copy_tree(tmp_path)
    target = tree / module
    target.write_text(target.read_text() + f"\n{statement}  # noqa\n")
    run = _lint_imports(tree)
    assert run.returncode != 0 and ", 0 broken" not in run.stdout
    assert contract in run.stdout.split("Broken contracts")[-1]


def _subpackage(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "aeromag_env" else parts[0]


def test_no_private_name_imported_across_subpackages() -> None:
    offences = []
    for path in _sources():
        here = _subpackage(_module_name(path))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ImportFrom) or not node.module or node.level:
                continue
            if node.module.split(".")[0] not in PACKAGES or _subpackage(node.module) == here:
                continue
            offences += [
                f"{path.relative_to(ROOT)}:{node.lineno} {node.module}.{a.name}"
                for a in node.names
                if a.name.startswith("_") and not a.name.startswith("__")
            ]
    assert not offences, offences


def _too_many_parameters() -> list[str]:
    """Functions with more than MAX_PARAMETERS positional parameters."""
    found = []
    for path in _sources():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            if len(node.args.posonlyargs) + len(node.args.args) > MAX_PARAMETERS:
                found.append(f"{path.relative_to(ROOT)}:{node.name}")
    return found


def test_functions_take_few_positional_parameters() -> None:
    assert not _too_many_parameters(), _too_many_parameters()


def test_ruff_format_decides_the_layout() -> None:
    """Module size is a question for review, not a count; packing lines under ``# fmt: skip``
    to meet one is what this guards against."""
    skips = [
        f"{path.relative_to(ROOT)}:{i}"
        for path in _sources()
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if line.rstrip().endswith("# fmt: skip")
    ]
    assert len(skips) <= MAX_FMT_SKIPS, f"{len(skips)} '# fmt: skip' lines: {skips[:10]}"


def test_import_is_light() -> None:
    """``import aeromag_env`` (and building the single environment's module) pulls in none of
    the heavy optional packages, nor the compiled kernels, nor ``agents``."""
    code = (
        "import sys, aeromag_env; light = set(sys.modules);"
        "import aeromag_env.environment.env; env = set(sys.modules);"
        "print(' '.join(sorted(m for m in light if m.split('.')[0] in HEAVY + ('numba',)))); "
        "print(' '.join(sorted(m for m in env if m.split('.')[0] in HEAVY)))"
    ).replace("HEAVY", "('torch', 'stable_baselines3', 'matplotlib', 'agents', 'ray')")
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    on_import, on_env = run.stdout.split("\n")[:2]
    assert on_import == "", f"import aeromag_env loads {on_import}"
    assert on_env == "", f"the environment module loads {on_env}"


def test_public_api_resolves() -> None:
    assert set(aeromag_env.__all__) == {"ENV_ID", "__version__", *aeromag_env._PUBLIC}
    for name in aeromag_env.__all__:
        assert getattr(aeromag_env, name) is not None, name
    assert set(aeromag_env.__all__) <= set(dir(aeromag_env))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        aeromag_env.nope  # noqa: B018
