"""The import contracts of ``pyproject.toml`` (``[tool.importlinter]``), checked by ``lint-imports``: the
layers, optim without the domain, body without clips, and no library module importing the CLI."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _lint_imports(config: Path, cwd: Path, source: Path) -> subprocess.CompletedProcess[str]:
    """``lint-imports`` with ``config`` on the package found in ``source`` (put first on the path)."""
    exe = Path(sys.executable).with_name("lint-imports")
    found = str(exe) if exe.is_file() else shutil.which("lint-imports")
    assert found, "lint-imports is missing: install the dev extra (pip install -e '.[dev]'), which has import-linter"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(source), os.environ.get("PYTHONPATH")]))}
    return subprocess.run([found, "--no-cache", "--no-logo", str(config)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def test_import_contracts_are_kept():
    proc = _lint_imports(ROOT / "pyproject.toml", ROOT, ROOT / "src")
    assert proc.returncode == 0, ("an import breaks a contract of pyproject.toml [tool.importlinter] (a module may "
                                  f"not import a layer above its own):\n{proc.stdout}{proc.stderr}")


def test_imports_inside_functions_count(tmp_path):
    """A lower layer importing a higher one inside a function breaks the contract like a top-level import."""
    pkg = tmp_path / "layered"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "high.py").write_text("")
    (pkg / "low.py").write_text("def late():\n    from layered import high\n\n    return high\n")
    config = tmp_path / "contracts.toml"
    config.write_text('[tool.importlinter]\nroot_package = "layered"\n\n[[tool.importlinter.contracts]]\n'
                      'name = "layers"\ntype = "layers"\nlayers = ["layered.high", "layered.low"]\n')
    proc = _lint_imports(config, tmp_path, tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "layered.low -> layered.high (l.2)" in proc.stdout
