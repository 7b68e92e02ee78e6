"""Bad and edge inputs of ``dipenv`` (issue 45): every one is refused with the project's message naming it,
before anything in the env changes, and long schedules are fast.

* schedules: one check (:func:`dipenv.schedules.validate_schedule`) for types, lengths, times, rates and
  a length cap; a rate of 1e-9 (which gave eta_r = -2.7e7) is refused;
* a 100,000-knot schedule used to take minutes per control interval (``sim.variants`` scans and converts
  every knot per look-up, once per piece): now about a second, and bit for bit the same episode;
* a refused reset leaves the env usable, also through ``gymnasium.make``;
* a misspelled reset option is answered with the options of the env's own class;
* constructor arguments, ``fixed_schedule`` and actions of the wrong kind.
"""

from __future__ import annotations

import math
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import dipenv
import sim
from dipenv.envs.thickening_control import ThickeningControlEnv
from dipenv.schedules import MAX_SCHEDULE_KNOTS, schedule_window, validate_schedule
from sim.variants import pieces

TINY = "dipenv/ThickeningControlTiny-v0"


@pytest.fixture(scope="module")
def library_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("inputs_library")


@pytest.fixture(scope="module")
def tiny(library_root: Path) -> Iterator[gym.Env]:
    env = gym.make(TINY, library_root=library_root, progress=False)
    yield env
    env.close()


# -- 1. one schedule check -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("schedule", "needle"),
    [
        ("fast", "must be {'times'"),
        (None, "must be {'times'"),
        (3.0, "must be {'times'"),
        ([[0.0, 1.0], [1.0, [2.0]]], r"rates\[1\] must be a real number, got \[2.0\] \(list\)"),
        ({"times": [0.0, 1.0]}, "exactly the keys 'times' and 'rates'"),
        ({"times": [0.0, 1.0], "rates": [1.0, 2.0], "extra": 1}, "exactly the keys"),
        ({"times": "01", "rates": [1.0, 2.0]}, "times must be a list of real numbers"),
        ({"times": [0.0, "1"], "rates": [1.0, 2.0]}, r"times\[1\] must be a real number"),
        ({"times": [0.0, 1.0], "rates": [1.0, True]}, r"rates\[1\] must be a real number, got True"),
        ({"times": [0.0, 1.0], "rates": [None, 1.0]}, r"rates\[0\] must be a real number"),
        ({"times": np.zeros((2, 2)), "rates": [1.0, 2.0]}, "array of shape"),
        ({"times": [], "rates": []}, "at least one"),
        ({"times": [0.0, 1.0], "rates": [1.0]}, "2 times and 1 rates"),
        ({"times": [0.0, math.nan], "rates": [1.0, 1.0]}, r"times\[1\] must be finite"),
        ({"times": [0.0, math.inf], "rates": [1.0, 1.0]}, r"times\[1\] must be finite"),
        ({"times": [0.5, 1.0], "rates": [1.0, 1.0]}, "must start at 0"),
        ({"times": [0.0, 1.0, 0.5], "rates": [1.0, 1.0, 1.0]}, r"times must increase .* times\[2\] = 0.5"),
        ({"times": [0.0, 0.0, 1.0], "rates": [1.0, 2.0, 2.0]}, "no jump at time 0"),
        ({"times": [0.0, 1.0, 1.0, 1.0], "rates": [1.0, 2.0, 3.0, 3.0]}, "at most two knots"),
        ({"times": [0.0, 1.0], "rates": [1e-9, 1e-9]}, r"rates\[0\] must be a finite rate in"),
        ({"times": [0.0, 1.0], "rates": [1.0, 0.0]}, "needs shear"),
        ({"times": [0.0, 1.0], "rates": [1.0, -1.0]}, r"rates\[1\] must be a finite rate"),
        ({"times": [0.0, 1.0], "rates": [1.0, 5e3]}, r"\[0.001, 1000\]"),
        ({"times": [0.0, 1.0], "rates": [1.0, math.nan]}, "finite rate"),
        (([0.0, 1.0], [1.0, math.inf]), "finite rate"),
        ((0.0, 1.0), "times must be a list of real numbers"),
        (
            {"times": list(range(MAX_SCHEDULE_KNOTS + 1)), "rates": [1.0] * (MAX_SCHEDULE_KNOTS + 1)},
            "more than the cap of 100000",
        ),
    ],
)
def test_malformed_schedules_get_the_project_s_message(schedule: object, needle: str) -> None:
    """Was: Python's ``TypeError``/``float()`` messages for nested lists, ``None`` taken as "no schedule",
    rate 1e-9 accepted (eta_r = -2.7e7), times not starting at 0 or with jumps, no length cap."""
    with pytest.raises(ValueError, match=needle) as caught:
        validate_schedule(schedule)
    assert str(caught.value).startswith("schedule")


def test_every_accepted_form_gives_the_same_schedule() -> None:
    times, rates = [0.0, 1.0, 2.5], [0.5, 2.0, 2.0]
    expected = sim.PiecewiseLinear(tuple(times), tuple(rates))
    forms = [
        {"times": times, "rates": rates},
        {"times": tuple(times), "rates": np.array(rates)},
        (times, rates),
        [np.array(times), [np.float32(0.5), 2, np.int64(2)]],
        expected,
        {"times": [0.0], "rates": [sim.MIN_SHEAR_RATE]},
    ]
    jump = validate_schedule({"times": [0.0, 1.0, 1.0, 2.0], "rates": [2.0, 2.0, 0.5, 0.5]})
    assert (jump(0.999), jump(1.0)) == (2.0, 0.5)  # two equal times: a jump, as in sim.PiecewiseLinear
    for form in forms[:-1]:
        assert validate_schedule(form) == expected
    assert validate_schedule(forms[-1])(7.0) == sim.MIN_SHEAR_RATE  # one knot: a constant rate


def test_the_shipped_schedules_pass_the_check() -> None:
    from dipenv.schedules import FIXED_SPLITS, fixed_schedules

    for split in FIXED_SPLITS:
        for schedule in fixed_schedules(split):
            assert validate_schedule(schedule) == schedule


# -- 2. long schedules ----------------------------------------------------------------------------------


def _random_schedule(rng: np.random.Generator, n: int, duration: float, jumps: bool) -> sim.PiecewiseLinear:
    times = np.sort(rng.uniform(0.0, duration, n))
    times[0] = 0.0
    if jumps:  # equal times (the simulator's own schedules may have them; validate_schedule refuses them)
        times[5::7] = times[4::7][: len(times[5::7])]
    rates = np.exp(rng.uniform(math.log(0.2), math.log(5.0), n))
    rates[10:20] = rates[10]  # a hold
    return sim.PiecewiseLinear(tuple(times), tuple(rates))


@pytest.mark.parametrize("jumps", [False, True])
def test_the_window_is_the_schedule_bit_for_bit(jumps: bool) -> None:
    """:func:`schedule_window` changes no value, mean, piece or piece mean that ``sim.follow`` reads on the
    way from ``start`` to ``end``: the same knots, the same arithmetic."""
    rng = np.random.default_rng(45)
    schedule = _random_schedule(rng, 3000, 12.0, jumps)
    for start, length in [(0.0, 0.25), (0.0, 0.0), (5.0, 0.25), (11.9, 0.5), (13.0, 0.25), (3.3, 2.0)]:
        start = start + float(rng.uniform(0.0, 0.01)) if start else start
        end = start + length
        window = schedule_window(schedule, start, end)
        assert len(window.times) < 0.2 * len(schedule.times) + 10
        probes = [start, end, *rng.uniform(start, end, 50), *(t for t in schedule.times if start <= t <= end)]
        for t in probes:
            assert window(t) == schedule(t)
        for max_piece in (0.05, 0.001):
            cut = pieces(schedule, start, end, max_piece)
            assert pieces(window, start, end, max_piece) == cut
            for a, b in cut:
                assert window.mean(a, b) == schedule.mean(a, b)
                assert window.is_constant_on(a, b) == schedule.is_constant_on(a, b)


def test_a_long_schedule_plays_the_episode_of_a_plain_simulation_bit_for_bit(tiny: gym.Env) -> None:
    """The env follows a 2,000-knot schedule through windows; a plain ``sim.follow`` of the whole schedule
    gives the same trajectory bit for bit."""
    env: ThickeningControlEnv = tiny.unwrapped
    rng = np.random.default_rng(3)
    n = 2000
    times = np.linspace(0.0, env.episode_duration, n)
    rates = np.exp(rng.uniform(math.log(0.3), math.log(4.0), n))
    schedule = {"times": times.tolist(), "rates": rates.tolist()}
    tiny.reset(seed=0, options={"split": "test", "index": 0, "schedule": schedule})
    start = env.library().load("test", 0, progress=False)
    action = np.array([0.2], dtype=np.float32)
    steps = 3
    for _ in range(steps):
        tiny.step(action)
    plain = sim.Simulation(env._simulation.config, start.state, keep_records=False)
    plain.set_field(env.mapping.mason_number(float(action[0])), (0.0, 1.0, 0.0))
    whole = sim.PiecewiseLinear(tuple(times), tuple(rates))
    origin = plain.state.time
    for k in range(steps):
        end = origin + k * env.control_interval + env.control_interval  # the env's arithmetic
        sim.follow(plain, end, whole, env.max_piece, origin=origin)
    np.testing.assert_array_equal(env._simulation.state.positions, plain.state.positions)
    assert env._simulation.state.strain == plain.state.strain


class _TooSlow(Exception):
    pass


def test_a_100000_knot_schedule_is_fast(tiny: gym.Env) -> None:
    """Was: minutes per control interval (the issue: a 100,000-point schedule hangs for more than 100 s).
    ``sim.variants`` converts all n knots to an array per look-up and scans them per piece, so an interval
    with m knots cost O(m n): here m = 10,000 (the cap's knots over the tiny episode), about 400 s per
    interval. Now about a second (the window holds the m knots and bisects them)."""
    env: ThickeningControlEnv = tiny.unwrapped
    n = MAX_SCHEDULE_KNOTS
    times = np.linspace(0.0, env.episode_duration, n)
    rates = 1.0 + 0.5 * np.sin(np.arange(n))
    schedule = {"times": times.tolist(), "rates": rates.tolist()}

    def too_slow(*_: object) -> None:
        raise _TooSlow

    previous = signal.signal(signal.SIGALRM, too_slow)
    signal.alarm(120)  # fail, rather than hang, on the slow path
    try:
        begin = time.perf_counter()
        _, info = tiny.reset(seed=0, options={"split": "test", "index": 0, "schedule": schedule})
        for _ in range(2):
            _, _, terminated, _, info = tiny.step(np.array([0.0], dtype=np.float32))
            assert not terminated
        elapsed = time.perf_counter() - begin
    except _TooSlow:
        pytest.fail("a reset and two steps on a 100,000-knot schedule took more than 120 s")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert elapsed < 30.0, elapsed
    assert info["shear_rate"] == pytest.approx(1.0, abs=0.5)


# -- 3. a refused reset changes nothing --------------------------------------------------------------------


BAD_OPTIONS = [
    {"schedules": {"times": [0.0], "rates": [1.0]}},
    {"schedule": "fast"},
    {"schedule": None},
    {"schedule": {"times": [0.0, 1.0], "rates": [1e-9, 1.0]}},
    {"split": "bogus"},
    {"split": "test", "index": 99},
    {"index": -1},
    {"index": True},
    {"volume_fraction": "0.4"},
    {"volume_fraction": 0.9},
    {"realisation": -1},
]


@pytest.mark.parametrize("options", [BAD_OPTIONS[0], BAD_OPTIONS[3], ["split"]])
def test_a_refused_first_reset_leaves_a_made_env_usable(library_root: Path, options: object) -> None:
    """Was: after a refused ``reset``, the next valid ``step`` failed with ``TypeError: cannot unpack
    non-iterable NoneType``: Gymnasium's ``PassiveEnvChecker`` (which ``gym.make`` added) marks its reset
    check done before the reset returns. The ids now register without it (the tests run the full checkers)
    and the env refuses before it changes anything."""
    env = gym.make(TINY, library_root=library_root, progress=False)
    with pytest.raises(ValueError):
        env.reset(options=options)  # type: ignore[arg-type]
    env.reset(seed=0, options={"split": "test", "index": 0})
    observation, reward, terminated, truncated, info = env.step(np.array([0.0], dtype=np.float32))
    assert env.observation_space.contains(observation) and math.isfinite(reward) and not terminated
    assert gym.spec(TINY).disable_env_checker


def test_every_id_registers_without_the_passive_checker() -> None:
    for env_id in dipenv.ENV_IDS:
        assert gym.spec(env_id).disable_env_checker, env_id


def _snapshot(env: ThickeningControlEnv) -> tuple[object, ...]:
    simulation = env._simulation
    assert simulation is not None
    return (
        simulation.state.positions.copy(),
        simulation.state.time,
        simulation.shear_rate,
        env._steps,
        env._needs_reset,
        env._schedule,
        env._cycle,
        repr(env.np_random.bit_generator.state),
        [f.copy() for f in env._frames],
    )


def test_a_refused_reset_mid_episode_changes_nothing(tiny: gym.Env) -> None:
    """Was: ``ThickeningControl`` reset the episode first and checked the schedule after (a rate of 1e-9
    left a half-reset env whose next step failed), and ``np_random`` was reseeded before the options were
    checked."""
    env: ThickeningControlEnv = tiny.unwrapped
    tiny.reset(seed=0, options={"split": "test", "index": 1})
    tiny.step(np.array([0.0], dtype=np.float32))
    before = _snapshot(env)
    for options in BAD_OPTIONS:
        with pytest.raises(ValueError):
            tiny.reset(seed=5, options=options)
        after = _snapshot(env)
        np.testing.assert_array_equal(after[0], before[0])  # type: ignore[arg-type]
        assert after[1:8] == before[1:8], options
        for a, b in zip(after[8], before[8], strict=True):  # type: ignore[call-overload]
            np.testing.assert_array_equal(a, b)
    *_, info = tiny.step(np.array([0.0], dtype=np.float32))  # the episode goes on
    assert info["time"] == pytest.approx(2 * env.control_interval)


# -- 4. the options of the env's class ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("env_id", "listed"),
    [
        (TINY, "split, index, volume_fraction, realisation, schedule"),
        ("dipenv/FieldMagnitudeTiny-v0", "split, index, volume_fraction, realisation"),
    ],
)
def test_a_misspelled_option_is_answered_with_the_env_s_options(
    library_root: Path, env_id: str, listed: str
) -> None:
    """Was: ``"schedules"`` on a thickening-control env was answered with a list that left out
    ``schedule`` (the field-control base class's list)."""
    env = gym.make(env_id, library_root=library_root, progress=False)
    with pytest.raises(ValueError) as caught:
        env.reset(options={"schedules": [], "splt": "test"})
    message = str(caught.value)
    assert "unknown reset options ['schedules', 'splt']" in message
    assert message.endswith(f"accepts: {listed}")
    assert ", ".join(env.unwrapped.reset_options) == listed


# -- 5. arguments, fixed schedules and actions --------------------------------------------------------------


@pytest.mark.parametrize(
    ("env_id", "kwargs", "needle"),
    [
        ("dipenv/FieldMagnitudeTiny-v0", {"mason_min": "x"}, "mason_min must be a finite real number > 0"),
        ("dipenv/FieldMagnitudeTiny-v0", {"off_band": "x"}, "off_band must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"control_interval": True}, "control_interval must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"target_viscosity": -1.0}, "target_viscosity must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"energy_weight": True}, "energy_weight must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"failure_penalty": "x"}, "failure_penalty must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"actuator_time_constant": "x"}, "actuator_time_constant must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"preshear_strain": 0.0}, "preshear_strain must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"preshear_strain": -1.0}, "preshear_strain must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"simulation_overrides": {"bogus": 1}}, "'bogus' is not a"),
        ("dipenv/FieldMagnitudeTiny-v0", {"simulation_overrides": {"n_particles": 64}}, "set by the env"),
        ("dipenv/FieldMagnitudeTiny-v0", {"simulation_overrides": {"time_step": -1}}, "time_step must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"simulation_overrides": "x"}, "simulation_overrides must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"library_root": 3}, "library_root must be"),
        ("dipenv/FieldMagnitudeTiny-v0", {"progress": "yes"}, "progress must be True or False"),
        (TINY, {"eta_cap": -1.0}, "eta_cap must be a finite real number > 0"),
        (TINY, {"eta_cap": math.nan}, "eta_cap must be"),
        (TINY, {"eta_cap": True}, "eta_cap must be"),
        (TINY, {"rate_range": (1e-9, 1.0)}, "rate_range must be .*MIN_SHEAR_RATE"),
        (TINY, {"rate_range": (0.5, 5e3)}, r"rate_range must be .*MAX_SHEAR_RATE = 1000 .*got \(0.5, 5000"),
        (TINY, {"rate_range": "ab"}, "rate_range must be two finite real numbers"),
        (TINY, {"rate_range": None}, "rate_range must be two"),
        (TINY, {"hold_range": (1, 2, 3)}, "hold_range must be two"),
        (TINY, {"ramp_range": None}, "ramp_range must be two"),
        (TINY, {"max_piece": "x"}, "max_piece must be"),
        (TINY, {"actuator_time_constant": "x"}, "actuator_time_constant must be 0"),
    ],
)
def test_bad_arguments_are_refused_at_make_by_name(
    library_root: Path, env_id: str, kwargs: dict[str, object], needle: str
) -> None:
    """Were: Python's ``TypeError``/``float()`` messages (strings), accepted (a bool, a negative target
    or cap, a zero pre-shear that failed at the first reset, rate ranges outside the simulator's range
    that failed at a reset, unknown or env-set simulation overrides that failed at the first reset)."""
    with pytest.raises(ValueError, match=needle):
        gym.make(env_id, **{"library_root": library_root, "progress": False, **kwargs})


def test_fixed_schedule_refuses_the_train_split_and_bad_indices(tiny: gym.Env) -> None:
    """Was: ``KeyError: 'train'`` (``agents.controllers --split train`` showed it)."""
    env: ThickeningControlEnv = tiny.unwrapped
    with pytest.raises(ValueError, match="train episodes draw"):
        env.fixed_schedule("train", 0)
    with pytest.raises(ValueError, match=r"index must be an integer in \[0, 2\) for split 'test'"):
        env.fixed_schedule("test", 2)
    with pytest.raises(ValueError, match="index must be an integer"):
        env.fixed_schedule("validation", True)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "action",
    [np.array([True]), np.array([0.5 + 0.5j]), np.array([0.5], dtype=object), [0.1, 0.2], "0.5", None],
)
def test_actions_of_the_wrong_kind_are_refused_before_anything_changes(tiny: gym.Env, action: object) -> None:
    env: ThickeningControlEnv = tiny.unwrapped
    tiny.reset(seed=0, options={"split": "test", "index": 0})
    before = _snapshot(env)
    with pytest.raises(ValueError, match="action"):
        env.step(action)  # type: ignore[arg-type]
    after = _snapshot(env)
    np.testing.assert_array_equal(after[0], before[0])  # type: ignore[arg-type]
    assert after[1:8] == before[1:8]
