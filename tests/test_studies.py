"""The studies: measured orders on the paper's chain, Dask and serial agree, the cost CSV is complete."""

import csv
import math

import numpy as np
import pytest

import thermonet as tn
from thermonet.errors import InputError
from thermonet.studies import Runner, asymptotic_slope, convergence_study, cost_study, energy_study
from thermonet.studies.scenes import check_scene

# every integrator that exists here, by the order it declares (implicit ones join when registered)
ORDERED = [n for n in ("gtr-0", "gtr-1", "gtr-1/2", "co2", "f10", "nm2", "co4", "ho4", "co6")
           if n in tn.available_integrators()]


@pytest.fixture(scope="module")
def dask_client():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0")
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_convergence_on_the_chain_measures_each_integrators_order():
    """The paper's §5.1.1 set-up: h = 0.1·2⁻ⁱ, i = 0…8, errors at t = 1."""
    study = convergence_study("chain", ORDERED, dt=0.1, halvings=8, t_end=1.0)
    assert max(study.reference.agreement.values()) < 1e-11
    for name in ORDERED:
        order = tn.get_integrator(name).order
        for q in ("position", "momentum", "temperature"):
            fit = study.slopes[(name, q)]
            assert fit.n_points >= 3, (name, q, fit)
            assert abs(fit.slope - order) <= 0.15, (name, q, fit.slope, order)


def test_dask_and_serial_give_identical_error_tables(dask_client):
    kwargs = dict(integrators=["gtr-1", "co2", "co4"], dt=0.1, halvings=3, t_end=1.0)
    serial = convergence_study("chain", runner=Runner(serial=True), **kwargs)
    with Runner(client=dask_client) as runner:
        on_dask = convergence_study("chain", runner=runner, **kwargs)
    assert on_dask.error_table() == serial.error_table()
    assert on_dask.reference.agreement == serial.reference.agreement


def test_runner_keeps_task_order_on_dask(dask_client):
    from thermonet.studies.tasks import check_steps

    tasks = [dict(t_end=1.0, h=1.0 / k) for k in (7, 3, 11, 1, 5, 2)]
    with Runner(client=dask_client) as runner:
        assert runner.map(check_steps, tasks) == [7, 3, 11, 1, 5, 2]
        assert runner.map(check_steps, tasks[:3], one_at_a_time=True) == [7, 3, 11]


def _distributed_log_level():
    import logging

    return logging.getLogger("distributed").getEffectiveLevel()


def test_a_runner_closes_its_own_cluster_with_the_workers_logs_silenced():
    """Closing a local cluster on a loaded machine can let a worker's heartbeat meet the
    scheduler already gone, and the worker then logs an error with a traceback after a study
    that succeeded; the runner silences the cluster's logs first and gives this process's back."""
    import logging

    pytest.importorskip("distributed")
    ours = _distributed_log_level()
    runner = Runner(n_workers=1)
    assert runner.client.run(_distributed_log_level) and runner.map(_distributed_log_level, [{}]) == [ours]
    runner._silence_workers()
    assert set(runner.client.run(_distributed_log_level).values()) == {logging.CRITICAL}
    runner.close()
    assert runner._cluster is None and _distributed_log_level() == ours


def test_cost_study_csv_has_every_requested_run(tmp_path):
    from thermonet.cli.main import main

    out = tmp_path / "cost"
    rc = main(["study", "cost", "chain", "--serial", "--quiet", "--integrators", "gtr-0,co2,co4", "--dt", "0.05",
               "--halvings", "2", "--repeats", "2", "--scipy", "DOP853:1e-4..1e-6,RK45:1e-4..1e-5", "--out", str(out)])
    assert rc == 0
    with open(out / "cost.csv") as f:
        rows = list(csv.DictReader(f))
    runs = {(r["solver"], float(r["h"])) for r in rows if not r["solver"].startswith("scipy")}
    assert runs == {(n, 0.05 / 2**i) for n in ("gtr-0", "co2", "co4") for i in range(3)}
    assert sorted(float(r["rtol"]) for r in rows if r["solver"] == "scipy-DOP853") == pytest.approx([1e-6, 1e-5, 1e-4])
    assert len([r for r in rows if r["solver"] == "scipy-RK45"]) == 2
    for r in rows:
        for col in ("time_median_s", "error_position", "error_momentum", "error_temperature"):
            assert math.isfinite(float(r[col])) and float(r[col]) >= 0, (r, col)
    assert (out / "cost_position.png").stat().st_size > 0
    assert "the cheapest is" in (out / "cost_summary.txt").read_text()


def test_cost_summary_names_the_cheapest_accurate_run():
    study = cost_study("chain", ["co2", "co4"], dt=0.05, halvings=3, repeats=1, scipy={"DOP853": [1e-6]})
    best = study.cheapest(1e-3)
    assert best is not None and best["position"] <= 1e-3
    assert all(r["time"] >= best["time"] for r in study.rows if r["position"] <= 1e-3)


def test_energy_study_conserves_entropy_and_angular_momentum(tmp_path):
    study = energy_study("chain", ["co2", "co4"], h=0.01, t_end=2.0, window=(0.5, 1.0))
    stats = study.statistics()
    for name in ("co2", "co4"):
        assert stats[name]["entropy_change"] == 0.0
        assert stats[name]["angular_momentum_change"] < 1e-10
        assert math.isnan(stats[name]["linear_momentum_change"])  # the chain is anchored
    assert stats["co4"]["energy_range_window"] < stats["co2"]["energy_range_window"]
    files = study.write(tmp_path)
    assert sum(f.endswith(".png") for f in files) == 4


def test_slope_fit_skips_floor_and_preasymptotic_points():
    h = 0.1 / 2.0 ** np.arange(10)
    error = 3.0 * h**2
    error[:2] *= [40.0, 6.0]          # pre-asymptotic
    error[-2:] = 1e-9                  # at the reference's floor
    fit = asymptotic_slope(h, error, floor=1e-8)
    assert fit.slope == pytest.approx(2.0, abs=1e-9)
    assert fit.h_max == pytest.approx(h[2]) and fit.h_min == pytest.approx(h[-3])


def test_unknown_scene_is_a_clear_input_error():
    with pytest.raises(InputError, match="neither a built-in scene"):
        check_scene("no-such-scene.toml")


def test_a_scene_file_gives_the_same_errors_as_the_builtin_chain():
    import pathlib

    path = pathlib.Path(__file__).resolve().parent.parent / "scenes" / "chain.toml"
    if not path.exists():
        pytest.skip("no scenes/chain.toml")
    kwargs = dict(integrators=["co2"], dt=0.1, halvings=2, t_end=1.0)
    from_file = convergence_study(str(path), **kwargs)
    builtin = convergence_study("chain", **kwargs)
    for a, b in zip(from_file.error_table(), builtin.error_table()):
        assert a[:2] == b[:2]
        assert np.allclose(a[2:], b[2:], rtol=1e-8, atol=1e-12)
