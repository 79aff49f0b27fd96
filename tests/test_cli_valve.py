"""``loopwatch simulate valve`` and ``loopwatch identify``: files, printed report, JSON, plot, and
one-line errors (exit status 2, no traceback) for bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from adapters.errors import DataFileError
from adapters.valve_csv import read_valve_csv, write_valve_csv
from models.karnopp import PRESETS
from service.cli import main


@pytest.fixture(scope="module")
def bench_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("valve")
    files = {}
    for test, seed in (("square", 1), ("triangle", 2), ("sine", 3)):
        files[test] = d / f"{test}.csv"
        assert main(["simulate", "valve", "--test", test, "--preset", "low", "--seed", str(seed),
                     "--out", str(files[test])]) == 0
    return files


def test_simulate_valve_writes_t_p_x_at_1ms(bench_files, capsys):
    data = read_valve_csv(bench_files["square"])
    assert data.t.size == 41600  # 4 periods of 10.4 s at 1 ms
    np.testing.assert_allclose(np.diff(data.t), 1e-3, rtol=1e-9)
    assert 41.74e3 < np.median(data.p) < 206.84e3
    assert 0.0 < data.x.min() and data.x.max() < 0.04


def test_simulate_valve_no_noise_and_errors(tmp_path, capsys):
    out = tmp_path / "isa.csv"
    assert main(["simulate", "valve", "--test", "isa-steps", "--preset", "high", "--no-noise", "--out", str(out)]) == 0
    data = read_valve_csv(out)
    assert np.all(data.x[:3000] == data.x[0])  # noise-free and stuck during the first hold
    capsys.readouterr()
    assert main(["simulate", "valve", "--test", "sine", "--preset", "low", "--noise-x", "-1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("loopwatch: error: --noise-x") and err.count("\n") == 1
    assert main(["simulate", "valve", "--test", "sine", "--preset", "low", "--fs-ratio", "0.5", "--out", str(out)]) == 2
    assert "fs_ratio" in capsys.readouterr().err


def test_identify_prints_writes_json_and_plot(bench_files, tmp_path, capsys):
    js, png = tmp_path / "out.json", tmp_path / "out.png"
    rc = main(["identify", str(bench_files["square"]), "--signature", str(bench_files["triangle"]),
               "--validate", str(bench_files["sine"]), "--json", str(js), "--plot", str(png)])
    assert rc == 0
    out = capsys.readouterr().out
    assert "model 1 (robust)" in out and "model 2" in out and "not identifiable" in out
    assert "validation sine.csv" in out
    doc = json.loads(js.read_text())
    truth = PRESETS["low"]
    m1 = doc["model1"]
    for key in ("m", "k", "Fc", "Fs", "Fv", "bias_m", "dv", "sigma", "r2"):
        assert key in m1 and key in doc["model2"]
    assert m1["k"] == pytest.approx(truth.k, rel=0.01)
    assert m1["Fc"] == pytest.approx(truth.fc, rel=0.03)
    assert m1["bias_m"] == pytest.approx(truth.bias, abs=0.05e-3)
    assert {v["model"] for v in doc["validation"]} == {"model 1 (robust)", "model 2"}
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "content, words",
    [
        ("t,p\n0,1\n", "missing column(s) x"),
        ("t,p,x\n0,1e5,0.01\n0.001,,0.01\n0.002,1e5,0.01\n", "line 3, column 'p'"),
        ("t,p,x\n0,1e5,0.01\n0,1e5,0.01\n", "not strictly increasing"),
        ("t,p,x\n" + "".join(f"{i * 1e-3},{1e5},{0.01}\n" for i in range(50)), "too short"),
        ("t,p,x\n" + "".join(f"{i * 1e-3},{1e5 + i},{0.01}\n" for i in range(2000)), "no stem motion"),
    ],
)
def test_identify_bad_input_is_one_line(tmp_path, capsys, content, words):
    f = tmp_path / "bad.csv"
    f.write_text(content)
    assert main(["identify", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("loopwatch: error:") and words in err and err.count("\n") == 1
    assert "Traceback" not in err


def test_identify_missing_file_and_bad_area(tmp_path, capsys, bench_files):
    assert main(["identify", str(tmp_path / "nope.csv")]) == 2
    assert "cannot open" in capsys.readouterr().err
    assert main(["identify", str(bench_files["square"]), "--area", "0"]) == 2
    assert "--area" in capsys.readouterr().err


def test_valve_csv_round_trip(tmp_path):
    t = np.arange(5) * 1e-3
    write_valve_csv(tmp_path / "r.csv", t, 1e5 + t, 0.01 + t)
    back = read_valve_csv(tmp_path / "r.csv")
    np.testing.assert_allclose(back.p, 1e5 + t)
    with pytest.raises(DataFileError):
        read_valve_csv(tmp_path / "missing.csv")
