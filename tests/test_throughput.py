"""ikbench bench --device: the throughput mode's files and figures (no timed assertions)."""

from __future__ import annotations

import json

import pandas as pd
import pytest
import torch

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.methods.ours_lm.devices import numba_installed
from ikbench.studies.throughput import parse_batches, parse_dtypes

HAVE_NUMBA = numba_installed()


def test_throughput_cli_on_cpu(tmp_path, capsys):
    assert main(["bench", "--device", "cpu", "--batches", "7,12", "--repeat", "1",
                 "--warmup", "0", "--steps", "10", "--quiet", "--output", str(tmp_path)]) == 0
    assert "device: cpu (" in capsys.readouterr().out
    table = pd.read_csv(tmp_path / "throughput.csv")
    cases = set(zip(table["backend"], table["dtype"], table["batch"]))
    backends = [("numpy", "float64"), ("torch", "float64"), ("torch", "float32")]
    if HAVE_NUMBA:
        backends.append(("numba", "float64"))
    assert cases == {(b, d, n) for n in (7, 12) for b, d in backends}
    float64 = table[(table["backend"] != "numpy") & (table["dtype"] == "float64")]
    assert (float64["loss_max_rel_diff"] < 1e-6).all()
    assert (table[table["dtype"] == "float32"]["loss_max_rel_diff"] < 1e-5).all()
    assert (table["converged_share"] == 1.0).all()
    assert (table[table["backend"] == "numpy"]["speedup_vs_numpy"] == 1.0).all()
    record = json.loads((tmp_path / "throughput.json").read_text())
    assert record["device"] == "cpu" and record["device_name"] and record["torch"]
    runs = pd.read_csv(tmp_path / "throughput_runs.csv")
    assert len(runs) == 2 * len(backends) and (runs["wall_s"] > 0).all()
    text = (tmp_path / "throughput.md").read_text()
    assert "| torch | float32 | 12 |" in text
    if HAVE_NUMBA:
        assert "| numba | float64 | 7 |" in text and record["numba_threads"] >= 1
        assert "one thread per 16 trajectories" in record["numba_threads_rule"]
        assert "largest relative difference of a final loss from numpy's, numba" in text


def test_throughput_without_numba_times_numpy_and_torch(tmp_path):
    assert main(["bench", "--device", "cpu", "--batches", "3", "--repeat", "1", "--warmup",
                 "0", "--steps", "8", "--dtypes", "float64", "--no-numba", "--quiet",
                 "--output", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "throughput.csv")
    assert set(table["backend"]) == {"numpy", "torch"}
    assert json.loads((tmp_path / "throughput.json").read_text())["numba"] is None
    assert "numba backend not timed" in (tmp_path / "throughput.md").read_text()


@pytest.mark.parametrize("args, message", [
    (["--device", "cpu", "--methods", "ours"], "--methods: not with --device"),
    (["--device", "cpu", "--batches", "7,0"], "--batches: '7,0' is not a list of batch sizes"),
    (["--device", "cpu", "--dtypes", "half"], "--dtypes: 'half' is not a list of float64"),
    (["--device", "tpu"], "--device: 'tpu' is not cpu, cuda or cuda:N"),
])
def test_throughput_bad_input_one_line_exit_2(tmp_path, capsys, args, message):
    assert main(["bench", *args, "--output", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "b").exists()


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_throughput_on_cuda_without_cuda_is_refused(tmp_path, capsys):
    assert main(["bench", "--device", "cuda", "--output", str(tmp_path)]) == 2
    assert "--device cuda: CUDA is not available here" in capsys.readouterr().err


def test_parsers():
    assert parse_batches("7, 1000,7") == [7, 1000]
    assert parse_dtypes("float32") == ["float32"]
    with pytest.raises(InputError):
        parse_batches("x")
