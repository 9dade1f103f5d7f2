"""Dask is an optional dependency (``pip install 'greyfmu[dask]'``): only ``cosim sweep
--scheduler`` needs it, and without it that option says how to get it."""
from __future__ import annotations

import subprocess
import sys

import pytest

from cosim.cli import main


def test_without_dask_the_scheduler_option_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)        # import distributed -> ImportError
    status = main(["sweep", "ssp/pid_fopdt", "--set", "controller.Kc=8", "--stop", "1",
                   "--scheduler", "local:1", "--output", str(tmp_path), "--quiet"])
    assert status == 2
    err = capsys.readouterr().err
    assert "need Dask, which is not installed" in err and "pip install 'greyfmu[dask]'" in err


def test_the_master_and_its_process_pool_sweeps_import_no_dask(tmp_path):
    code = ("import sys; sys.modules['dask'] = sys.modules['distributed'] = None\n"
            "from cosim.cli import main\n"
            f"sys.exit(main(['sweep', 'ssp/pid_fopdt', '--set', 'controller.Kc=6,8', '--stop', '1', "
            f"'--workers', '2', '--output', {str(tmp_path)!r}]))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "2 runs (2 ran now" in done.stdout


def test_without_cryptography_a_local_cluster_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    # cryptography makes the local:N cluster's TLS key and certificate (part of greyfmu[dask])
    pytest.importorskip("distributed")
    monkeypatch.setitem(sys.modules, "cryptography", None)
    status = main(["sweep", "ssp/pid_fopdt", "--set", "controller.Kc=8", "--stop", "1",
                   "--scheduler", "local:1", "--output", str(tmp_path), "--quiet"])
    assert status == 2
    err = capsys.readouterr().err
    assert "needs the package cryptography" in err and "pip install 'greyfmu[dask]'" in err
