"""A curve sample's measures on the device (engine.cuda.measures) and simulations stepped side
by side on one device (engine.cuda.batch), under numba-cuda's simulator: the two cases run in
one process of their own, once a session (tests/engine/cuda_measure_cases.py), as
tests/engine/test_cuda.py runs its cases. Tiny scenes, a few steps."""

from __future__ import annotations

import pytest

from tests.engine.test_cuda import _python, case_result, needs_numba_cuda, simulator_cases

#: The device sums the host's terms in another order (per particle, then per chunk of 64, then
#: a fixed tree, against contact by contact in the host's order): each sum differs by a few
#: float64 roundings of its largest partial sums, relative 1e-15 here; a wrong term (a contact
#: missed or counted twice, a sign, a lever) moves a measure by 1e-3 or more.
REL = 1e-12


SPECS = ("measures:persistent:general", "batch:persistent:general")


@pytest.fixture(scope="module")
def cases(tmp_path_factory) -> dict:
    return simulator_cases(tmp_path_factory, "tests.engine.cuda_measure_cases", SPECS)


def _case(cases: dict, name: str) -> dict:
    return case_result(cases, f"{name}:persistent:general")


@needs_numba_cuda
def test_device_measures_equal_the_host_measures_without_pulling_the_state(cases):
    r = _case(cases, "measures")
    assert r["samples"] == 2
    for k, rel in r["rel"].items():
        assert rel <= REL, (k, rel, r)
    # every measure exercised: contacts inside and across the window, platen contacts
    assert r["contacts"] > 10 and r["interior_contacts"] > 5 and r["wall_contacts"] > 0, r
    assert 0 < r["interior_particles"] < 34, r
    for k in ("s_lat", "s_ver", "s_in", "ke", "coord_in"):
        assert r["abs"][k] > 0, (k, r)
    # a device sample (and the platen speed set before it, as each loading sample does)
    # copies none of the state's groups whole; the host's copies all three
    assert abs(r["platen_moved"] - 1.0) < 1e-9, r
    assert r["pulls_by_device_sample"] == {}, r
    assert r["pulls_by_host_sample"] == {"particles": 1, "walls": 1, "list": 1}, r
    assert r["device_twice_identical"], r
    # kinetic_energy, pair_stress and n_contacts of a CudaSimulation: summed on the device
    assert max(r["sums_rel"]) <= REL and r["pulls_by_device_sums"] == {}, r
    assert r["n_contacts"][0] == r["n_contacts"][1] > 10, r
    # the pour's speed cap on the device: the host's velocities and forces, no state copied
    assert r["capped"] == [True, True] and r["pulls_by_device_cap"] == {}, r
    for q, rel in r["cap_rel"].items():
        assert rel <= REL, (q, rel, r)
    assert r["fastest_over_cap"] <= 1 + 1e-12, r


@needs_numba_cuda
def test_three_scenes_side_by_side_equal_the_three_alone(cases):
    r = _case(cases, "batch")
    assert r["n"] == [24, 34, 28] and r["steps"] == [8, 8, 8], r
    assert r["streams_distinct"], r
    assert r["bit_identical"] and r["rel"] == 0.0, r
    assert min(r["contacts"]) > 0, r
    assert min(r["rebuilds"]) > 1, r  # lists rebuilt on the threads' streams too
    assert r["twice_refused"], r


def test_batch_arguments_are_checked():
    pytest.importorskip("numba_cuda")
    proc = _python(
        [
            "-c",
            "import engine\n"
            "from engine.cuda.batch import StreamExecutor, run_together, step_together\n"
            "for call in (lambda: run_together([]), lambda: StreamExecutor(0),\n"
            "             lambda: run_together([print], max_workers=0),\n"
            "             lambda: step_together([object()], 1)):\n"
            "    try:\n"
            "        call()\n"
            "        print('accepted')\n"
            "    except engine.ParameterError as e:\n"
            "        print(e.field)\n"
            "print(run_together([lambda: 1, lambda: 2]))\n"
            "done = []\n"
            "try:\n"
            "    run_together([lambda: 1 / 0, lambda: done.append(2)])\n"
            "except ZeroDivisionError:\n"
            "    print('raised after', done)\n",
        ],
        simulator=True,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    lines = proc.stdout.strip().splitlines()
    assert lines == [
        "run_together.tasks",
        "StreamExecutor.max_workers",
        "run_together.max_workers",
        "step_together.sims[0]",
        "[1, 2]",
        "raised after [2]",
    ], lines


@needs_numba_cuda
def test_a_cuda_study_worker_runs_its_runs_on_streams_of_one_process(tmp_path):
    pytest.importorskip("pydantic")
    code = (
        "from service.pools import run_executor\n"
        "from service.settings import Settings\n"
        f"s = Settings(data_dir={str(tmp_path)!r}, run_workers=3, backend='cuda')\n"
        "for backend in ('cuda', 'cpu'):\n"
        "    with run_executor(s, backend) as pool:\n"
        "        print(type(pool).__name__, pool._max_workers)\n"
        "with run_executor(s, 'cuda') as pool:\n"
        "    from engine.cuda.batch import current_stream\n"
        "    streams = {id(pool.submit(current_stream).result()) for _ in range(6)}\n"
        "    print(len(streams) <= 3, all(pool.submit(current_stream).result() is not None\n"
        "                                  for _ in range(3)))\n"
    )
    proc = _python(["-c", code], simulator=True)
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert proc.stdout.split("\n")[:3] == [
        "StreamExecutor 3",
        "ProcessPoolExecutor 3",
        "True True",
    ], proc.stdout
