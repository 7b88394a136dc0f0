"""The command line: results as a table or JSON, bad input -> one message and exit code 2."""
import json
import subprocess
import sys

import pytest

from fencesweep.cli import main


def test_run_json_small_far(capsys):
    assert main(["run", "--case", "small_far", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["outcome"] == "scraped" and res["status"] == "ok"
    assert {"peak_force", "overload", "deflection_max", "residual_deflection", "t_S4", "n_steps"} <= set(res)


def test_run_table_with_set(capsys):
    assert main(["run", "--case", "long_near", "--set", "drive=rigid", "--set", "t_c=1.36"]) == 0
    out = capsys.readouterr().out
    assert "outcome" in out and "scraped" in out and "peak_force" in out and " N" in out


def test_run_impact_and_freefall(capsys):
    assert main(["run", "--scene", "freefall", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["peak_force"] == pytest.approx(6414, abs=1)
    assert main(["run", "--scene", "impact", "--set", "drive=free", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["e_eff"] < 0.2


@pytest.mark.parametrize("args, msg", [
    (["run", "--set", "B3=1"], "did you mean 'B2'"),
    (["run", "--set", "m1=-2"], "m1 = -2.0 is out of range"),
    (["run", "--set", "B2"], "is not NAME=VALUE"),
    (["run", "--set", "dP=0.7"], "dP = 0.7 is not allowed"),
])
def test_bad_input_exit_code_2(args, msg, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err


def test_trajectory_written_for_plotting(tmp_path):
    pd = pytest.importorskip("pandas")
    path = tmp_path / "traj.parquet"
    assert main(["run", "--case", "small_far", "--trajectory", str(path)]) == 0
    df = pd.read_parquet(path)
    assert {"t", "x", "y", "phi", "alpha", "alpha_w", "N_fence", "N_rail", "stage"} <= set(df.columns)
    assert df.t.is_monotonic_increasing and df.N_fence.max() > 1000


def test_console_script_runs_as_a_user_would():
    r = subprocess.run([sys.executable, "-m", "fencesweep.cli", "run", "--set", "e=2"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "e = 2.0 is out of range" in r.stderr


def test_version_is_the_installed_metadata(capsys):
    from importlib import metadata

    import fencesweep
    from fencesweep.study.store import table as store

    version = metadata.version("fencesweep")  # pyproject.toml's, the one place it is written
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out == f"fencesweep {version}\n"
    assert fencesweep.__version__ == version == store.versions()["fencesweep"]


def test_python_dash_m_fencesweep():
    r = subprocess.run([sys.executable, "-m", "fencesweep", "--version"], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.startswith("fencesweep ")
    r = subprocess.run([sys.executable, "-m", "fencesweep", "run", "--set", "e=2"], capture_output=True, text=True)
    assert r.returncode == 2 and "e = 2.0 is out of range" in r.stderr and "Traceback" not in r.stderr


def _strict_json(text: str):
    """json.loads that refuses NaN and Infinity, as a JSON parser of another language does."""
    def refuse(constant):
        raise ValueError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_run_json_undefined_values_are_null(capsys):
    # the load starts 20 m upstream: no contact before t_max, so t_first_contact is undefined
    assert main(["run", "--set", "R_s=-20", "--set", "t_max=1.36", "--json"]) == 0
    out = capsys.readouterr().out
    res = _strict_json(out)
    assert res["outcome"] == "timeout" and res["t_first_contact"] is None
    assert "NaN" not in out and res["peak_force"] == 0.0 and res["n_impacts"] == 0
    assert main(["run", "--case", "small_far", "--json"]) == 0  # a run with contact: a number
    assert isinstance(_strict_json(capsys.readouterr().out)["t_first_contact"], float)


def test_the_parser_imports_neither_pandas_nor_numba():
    """Every command builds the whole parser; pandas (0.2 s) and Numba (0.25 s) are imported
    only by the commands that use them, so `--help` and a rejected argument answer at once."""
    code = ("import sys\nfrom fencesweep.cli import build_parser\nbuild_parser()\n"
            "print(sorted(m for m in ('pandas', 'numba', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
