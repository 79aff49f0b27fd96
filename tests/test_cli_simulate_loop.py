"""``loopwatch simulate loop``: CSV output, printed truth, errors as exit status 2."""

from __future__ import annotations

import numpy as np
import pytest

from adapters.csv_table import read_table
from service.cli import main

COLUMNS = ("t", "sp", "pv", "op", "mv", "mode")
EXPECTED_TRUTH = {
    "healthy": "healthy",
    "tuning": "tuning",
    "disturbance": "disturbance",
    "tuning+disturbance": "tuning+disturbance",
    "stiction-datadriven": "stiction",
    "stiction-lugre": "stiction",
    "deadband": "deadband",
}


@pytest.mark.parametrize("case", list(EXPECTED_TRUTH))
def test_every_case_writes_a_loop_csv(case, tmp_path, capsys):
    out = tmp_path / f"{case}.csv"
    rc = main(["simulate", "loop", "--case", case, "--duration", "120", "--out", str(out)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert case in printed and f"truth {EXPECTED_TRUTH[case]}" in printed
    table = read_table(out, required=COLUMNS)
    assert list(table) == list(COLUMNS)
    np.testing.assert_array_equal(table["t"], np.arange(120.0))
    assert np.all(table["mode"] == 1.0)
    assert np.all(np.isfinite(np.column_stack([table[c] for c in COLUMNS])))
    assert table["sp"][-1] == 5.0  # every case starts with a set-point step to 5 at t = 50 s


def test_header_order_and_defaults(tmp_path):
    out = tmp_path / "tuning.csv"
    assert main(["simulate", "loop", "--case", "tuning", "--out", str(out)]) == 0
    assert out.read_text().splitlines()[0] == ",".join(COLUMNS)
    table = read_table(out, required=COLUMNS)
    assert table["t"].size == 4000  # the paper's 4000 s at 1 s


def test_noise_and_seed(tmp_path):
    a, b, c = (tmp_path / n for n in ("a.csv", "b.csv", "c.csv"))
    base = ["simulate", "loop", "--case", "healthy", "--duration", "300", "--noise", "0.2"]
    assert main([*base, "--seed", "4", "--out", str(a)]) == 0
    assert main([*base, "--seed", "4", "--out", str(b)]) == 0
    assert main([*base, "--seed", "5", "--out", str(c)]) == 0
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()


@pytest.mark.parametrize(
    "extra, word",
    [
        (["--noise", "-1"], "--noise"),
        (["--noise", "nan"], "--noise"),
        (["--duration", "0"], "--duration"),
        (["--duration", "10.5"], "duration_s"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(extra, word, tmp_path, capsys):
    rc = main(["simulate", "loop", "--case", "tuning", *extra, "--out", str(tmp_path / "x.csv")])
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith("loopwatch: error:") and word in err
    assert "Traceback" not in err
    assert not (tmp_path / "x.csv").exists()


def test_unknown_case_is_rejected_by_the_parser(tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "loop", "--case", "gremlins", "--out", str(tmp_path / "x.csv")])
    assert exc.value.code == 2
