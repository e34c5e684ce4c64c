"""Rule-based maintenance policies (agents.policies) on hand-built observations, and their evaluation."""

import math

import gymnasium as gym
import numpy as np
import pytest

import ea_gym  # noqa: F401 - registers the environments
from agents import ActionMap, CorrectiveBand, EpisodeStats, Oracle, Periodic, RulThreshold, RunToFailure, evaluate, mean_ci95, tune

COMPONENTS = ("k", "m", "b")
CLASSES = ("none", *COMPONENTS)
MEANINGS = ("carry on", *(f"corrective action on {c}" for c in COMPONENTS), *(f"replace {c}" for c in COMPONENTS))
ACTIONS = ActionMap(MEANINGS, COMPONENTS, CLASSES)
NOMINAL_POSITIONS = (0.75, 0.5, 0.5)  # k = 100 in (85, 105), m = 10 in (9, 11), b = 0.5 in (0.4, 0.6)
REPLACE = {c: 4 + i for i, c in enumerate(COMPONENTS)}
CORRECT = {c: 1 + i for i, c in enumerate(COMPONENTS)}


def obs(diagnosed="none", rul_low=1000.0, since=0.0, down=0.0, mode="phm"):
    """One hand-built observation of the spring-mass-damper env (float32 arrays, the env's shapes)."""
    # the chain's diagnosis is exactly "none" before its alarm, and spreads its belief afterwards
    diagnosis = np.zeros(4, np.float32) if diagnosed == "none" else np.full(4, 0.02, np.float32)
    diagnosis[CLASSES.index(diagnosed)] = 1.0 if diagnosed == "none" else 0.94
    o = {
        "ea": np.ones(4, np.float32),
        "eai": np.full(3, 1 / 3, np.float32),
        "residual": np.zeros(4, np.float32),
        "time_since_maintenance": np.array([since], np.float32),
        "maintenance_in_progress": np.array([down], np.float32),
    }
    if mode != "sensors":
        o["diagnosis"] = diagnosis
        o["parameter_estimate"] = np.full(3, 0.5, np.float32)
        o["rul"] = np.array([rul_low + 5.0, rul_low, rul_low + 10.0], np.float32)
    return o


def batch(*observations):
    return {key: np.stack([o[key] for o in observations]) for key in observations[0]}


def act(policy, observation, **kwargs):
    action, _ = policy.predict(observation, **kwargs)
    assert isinstance(action, np.ndarray) and action.shape == () and np.issubdtype(action.dtype, np.integer)
    return int(action)


def test_action_map_matches_the_environment():
    env = gym.make("ea_gym/SpringMassDamper-v0", obs_mode="oracle")
    amap = ActionMap.from_env(env)
    assert amap.action_meanings == MEANINGS and amap.components == COMPONENTS and amap.diagnosis_classes == CLASSES
    assert amap.obs_mode == "oracle" and amap.nominal_positions == NOMINAL_POSITIONS
    assert [amap.replace(c) for c in COMPONENTS] == [4, 5, 6] and [amap.corrective(c) for c in COMPONENTS] == [1, 2, 3]
    with pytest.raises(ValueError, match="replace x"):
        amap.replace("x")
    with pytest.raises(TypeError, match="ActionMap"):
        ActionMap.from_env(object())


def test_run_to_failure_always_carries_on():
    policy = RunToFailure()
    for o in (obs(), obs("k", rul_low=0.0), obs(since=1e4), obs(mode="sensors")):
        assert act(policy, o) == 0
    actions, state = policy.predict(batch(obs(), obs("m", rul_low=0.0)))
    assert actions.shape == (2,) and actions.tolist() == [0, 0] and state is None


@pytest.mark.parametrize("cls", [RulThreshold, Oracle])
def test_rul_threshold_replaces_the_diagnosed_component_below_the_threshold(cls):
    policy = cls(ACTIONS, threshold=20.0)
    for c in COMPONENTS:
        assert act(policy, obs(c, rul_low=19.0)) == REPLACE[c]
        assert act(policy, obs(c, rul_low=21.0)) == 0  # above the threshold
        assert act(policy, obs(c, rul_low=19.0, down=1.0)) == 0  # orders are ignored while down
    assert act(policy, obs("none", rul_low=0.0)) == 0  # no fault believed: carry on
    # "none" outweighing the suspect does not hold it back: a finite RUL says the chain tracks that fault
    o = obs("b", rul_low=5.0)
    o["diagnosis"] = np.array([0.6, 0.1, 0.05, 0.25], np.float32)
    assert act(policy, o) == REPLACE["b"]
    # the lower bound of the interval decides, not the point estimate
    o = obs("m", rul_low=15.0)
    o["rul"] = np.array([25.0, 15.0, 40.0], np.float32)
    assert act(policy, o) == REPLACE["m"]
    corrective = cls(ACTIONS, threshold=20.0, action="corrective")
    assert act(corrective, obs("b", rul_low=3.0)) == CORRECT["b"]
    assert act(corrective, obs("b", rul_low=30.0)) == 0
    eager = cls(ACTIONS, threshold=math.inf)
    assert act(eager, obs("k", rul_low=1000.0)) == REPLACE["k"] and act(eager, obs()) == 0


def test_corrective_band_corrects_the_suspect_beyond_its_band_toward_either_limit():
    policy = CorrectiveBand(ActionMap(MEANINGS, COMPONENTS, CLASSES, "phm", NOMINAL_POSITIONS), band=0.5)

    def suspect(component, position, share_of_rest=0.02, down=0.0):
        o = obs(component, down=down)
        o["diagnosis"][1:] = share_of_rest
        o["diagnosis"][CLASSES.index(component)] = 0.5
        o["parameter_estimate"][COMPONENTS.index(component)] = position
        return o

    assert act(policy, suspect("b", 0.2)) == CORRECT["b"]  # 60 % of the way down from 0.5
    assert act(policy, suspect("b", 0.8)) == CORRECT["b"]  # 60 % of the way up
    assert act(policy, suspect("b", 0.3)) == 0  # 40 %: inside the band
    # k's nominal sits at 0.75 of its range: 0.9 is 60 % of the way up, 0.45 only 40 % of the way down
    assert act(policy, suspect("k", 0.9)) == CORRECT["k"]
    assert act(policy, suspect("k", 0.45)) == 0
    assert act(policy, suspect("m", 0.1)) == CORRECT["m"]
    # a suspect with less than 0.4 of the fault classes' belief, the machine down, or no fault: carry on
    assert act(policy, suspect("b", 0.1, share_of_rest=0.4)) == 0
    assert act(policy, suspect("b", 0.1, down=1.0)) == 0
    assert act(policy, obs("none")) == 0
    strict = CorrectiveBand(ActionMap(MEANINGS, COMPONENTS, CLASSES, "phm", NOMINAL_POSITIONS), 0.5, share=0.95)
    assert act(strict, suspect("b", 0.1)) == 0  # its share, 0.5 / 0.54 = 0.93, is below 0.95
    with pytest.raises(ValueError, match="sensors"):
        CorrectiveBand(ActionMap(MEANINGS, COMPONENTS, CLASSES, "sensors", NOMINAL_POSITIONS), 0.5)
    with pytest.raises(ValueError, match="nominal positions"):
        CorrectiveBand(ACTIONS, 0.5)
    with pytest.raises(ValueError, match="band"):
        CorrectiveBand(ActionMap(MEANINGS, COMPONENTS, CLASSES, "phm", NOMINAL_POSITIONS), 1.0)


def test_corrective_band_per_component_holds_each_component_in_its_own_band():
    phm = ActionMap(MEANINGS, COMPONENTS, CLASSES, "phm", NOMINAL_POSITIONS)
    policy = CorrectiveBand(phm, band={"k": 0.8, "m": 0.8, "b": 0.4})

    def suspect(component, position):
        o = obs(component)
        o["parameter_estimate"][COMPONENTS.index(component)] = position
        return o

    # b: 0.25 is 50 % of the way down from 0.5, beyond its 0.4; 0.32 is 36 %, inside
    assert act(policy, suspect("b", 0.25)) == CORRECT["b"] and act(policy, suspect("b", 0.32)) == 0
    # k: 0.97 is 88 % of the way up from 0.75, beyond its 0.8; 0.9 is 60 %, inside (a uniform 0.4 would act)
    assert act(policy, suspect("k", 0.97)) == CORRECT["k"] and act(policy, suspect("k", 0.9)) == 0
    assert act(policy, suspect("m", 0.05)) == CORRECT["m"] and act(policy, suspect("m", 0.15)) == 0
    # batched: each row is held to its own suspect's band
    actions, _ = policy.predict(batch(suspect("b", 0.25), suspect("k", 0.9), suspect("m", 0.05)))
    assert actions.tolist() == [CORRECT["b"], 0, CORRECT["m"]]
    assert policy.band == {"k": 0.8, "m": 0.8, "b": 0.4}
    with pytest.raises(ValueError, match=r"missing \['b'\]"):
        CorrectiveBand(phm, band={"k": 0.8, "m": 0.8})
    with pytest.raises(ValueError, match=r"unknown \['c'\]"):
        CorrectiveBand(phm, band={"k": 0.8, "m": 0.8, "b": 0.4, "c": 0.5})
    with pytest.raises(ValueError, match=r"band\['m'\] must be a fraction"):
        CorrectiveBand(phm, band={"k": 0.8, "m": 1.2, "b": 0.4})


def test_corrective_band_narrows_a_quiet_components_band():
    elements = ("F", "m", "k", "b")
    phm = ActionMap(MEANINGS, COMPONENTS, CLASSES, "phm", NOMINAL_POSITIONS, elements)
    policy = CorrectiveBand(phm, band={"k": 0.8, "m": 0.8, "b": 0.6}, quiet_band={"b": 0.3}, quiet_activity=0.003)

    def suspect(component, position, activity):
        o = obs(component)
        o["parameter_estimate"][COMPONENTS.index(component)] = position
        o["ea"][elements.index(component)] = activity
        return o

    # b at 0.3 is 40 % of the way down from 0.5: inside 0.6 while the damper is excited, beyond 0.3 while quiet
    assert act(policy, suspect("b", 0.3, 0.01)) == 0
    assert act(policy, suspect("b", 0.3, 0.002)) == CORRECT["b"]
    # the spring has no quiet band: a quiet step leaves its 0.8 (0.9 is 60 % of the way up)
    assert act(policy, suspect("k", 0.9, 0.0)) == 0
    actions, _ = policy.predict(batch(suspect("b", 0.3, 0.01), suspect("b", 0.3, 0.0)))
    assert actions.tolist() == [0, CORRECT["b"]]
    without_ea = suspect("b", 0.3, 0.0)
    del without_ea["ea"]
    with pytest.raises(ValueError, match="'ea'"):
        policy.predict(without_ea)
    with pytest.raises(ValueError, match="elements"):
        CorrectiveBand(ActionMap(MEANINGS, COMPONENTS, CLASSES, "phm", NOMINAL_POSITIONS), 0.5, quiet_band={"b": 0.3})
    with pytest.raises(ValueError, match=r"\['c'\] are not among the fault classes"):
        CorrectiveBand(phm, 0.5, quiet_band={"c": 0.3})
    with pytest.raises(ValueError, match=r"quiet_band\['b'\] must be a fraction"):
        CorrectiveBand(phm, 0.5, quiet_band={"b": 0.0})
    with pytest.raises(ValueError, match="quiet_activity"):
        CorrectiveBand(phm, 0.5, quiet_band={"b": 0.3}, quiet_activity=float("nan"))


def test_batched_observations_give_one_action_per_env():
    policy = RulThreshold(ACTIONS, 10.0)
    o = batch(obs("k", 5.0), obs("none", 0.0), obs("b", 50.0), obs("m", 1.0), obs("m", 1.0, down=1.0))
    actions, state = policy.predict(o, episode_start=np.zeros(5, bool))
    assert actions.shape == (5,) and actions.tolist() == [REPLACE["k"], 0, 0, REPLACE["m"], 0] and state is None
    one, _ = policy.predict(batch(obs("k", 5.0)))
    assert one.shape == (1,) and one.tolist() == [REPLACE["k"]]


def test_periodic_replaces_every_component_after_the_period_and_not_before():
    policy = Periodic(ACTIONS, period=60.0)
    assert act(policy, obs(since=0.0, mode="sensors"), episode_start=np.array([True])) == 0
    assert act(policy, obs(since=59.0, mode="sensors")) == 0
    assert act(policy, obs(since=60.0, mode="sensors")) == REPLACE["k"]
    # the replacement resets time_since_maintenance and stops the machine: wait, then the next one
    assert act(policy, obs(since=1.0, down=1.0, mode="sensors")) == 0
    assert act(policy, obs(since=2.0, down=1.0, mode="sensors")) == 0
    assert act(policy, obs(since=3.0, mode="sensors")) == REPLACE["m"]
    assert act(policy, obs(since=3.0, mode="sensors")) == REPLACE["b"]
    assert act(policy, obs(since=3.0, mode="sensors")) == 0  # round over
    assert act(policy, obs(since=59.0, mode="sensors")) == 0
    assert act(policy, obs(since=61.0, mode="sensors")) == REPLACE["k"]
    # a new episode ends the round
    assert act(policy, obs(since=0.0, mode="sensors"), episode_start=np.array([True])) == 0
    assert act(policy, obs(since=0.0, mode="sensors")) == 0


def test_periodic_state_round_trips_sb3_style_and_per_env():
    policy = Periodic(ACTIONS, period=30.0, components=("b", "k"))
    o = batch(obs(since=31.0, mode="sensors"), obs(since=5.0, mode="sensors"))
    actions, state = policy.predict(o, state=None, episode_start=np.ones(2, bool))
    assert actions.tolist() == [REPLACE["b"], 0] and state.tolist() == [1, -1]
    policy.reset()  # the state passed in wins over the policy's own memory
    actions, state = policy.predict(batch(obs(since=1.0, mode="sensors"), obs(since=30.0, mode="sensors")), state=state)
    assert actions.tolist() == [REPLACE["k"], REPLACE["b"]] and state.tolist() == [-1, 1]
    with pytest.raises(ValueError, match="state"):
        policy.predict(o, state=np.zeros(3, int))


def test_missing_keys_and_bad_shapes_raise_clear_errors():
    sensors = obs(mode="sensors")
    for policy in (RulThreshold(ACTIONS, 10.0), Oracle(ACTIONS, 10.0)):
        with pytest.raises(ValueError, match="'diagnosis'.*obs_mode"):
            policy.predict(sensors)
    no_rul = obs("k", 1.0)
    del no_rul["rul"]
    with pytest.raises(ValueError, match="'rul'"):
        RulThreshold(ACTIONS, 10.0).predict(no_rul)
    no_down = obs(mode="sensors")
    del no_down["maintenance_in_progress"]
    with pytest.raises(ValueError, match="'maintenance_in_progress'"):
        Periodic(ACTIONS, 10.0).predict(no_down)
    for policy in (RunToFailure(), Periodic(ACTIONS, 10.0), RulThreshold(ACTIONS, 10.0)):
        with pytest.raises(ValueError, match="'time_since_maintenance'"):
            policy.predict({"ea": np.ones(4)})
    with pytest.raises(TypeError, match="Dict observation"):
        RunToFailure().predict(np.zeros(8))
    with pytest.raises(ValueError, match="classes"):
        RulThreshold(ACTIONS, 10.0).predict({**obs("k", 1.0), "diagnosis": np.ones(5, np.float32)})
    # the env's mode is checked when the policy is built from it
    with pytest.raises(ValueError, match="sensors"):
        RulThreshold(gym.make("ea_gym/SpringMassDamper-v0", obs_mode="sensors"), 10.0)
    with pytest.raises(ValueError, match="oracle"):
        Oracle(gym.make("ea_gym/SpringMassDamper-v0", obs_mode="sensors"), 10.0)
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="threshold"):
            RulThreshold(ACTIONS, bad)
        with pytest.raises(ValueError, match="period"):
            Periodic(ACTIONS, bad)


def _oracle_env():
    return gym.make("ea_gym/SpringMassDamper-v0", obs_mode="oracle", horizon=20, continue_after_failure=True)


def test_evaluate_two_short_episodes_gives_consistent_numbers():
    stats = evaluate(Oracle(ACTIONS, 15.0), _oracle_env, seeds=[3, 4], progress=False)
    assert isinstance(stats, EpisodeStats) and stats.n == 2 and stats.seeds.tolist() == [3, 4]
    per = stats.per_episode
    assert per["steps"].tolist() == [20, 20]
    assert stats.mean_cost == pytest.approx(per["cost"].mean())
    low, high = stats.ci95
    assert low <= stats.mean_cost <= high
    breakdown = sum(per[f"cost_{item}"] for item in ("corrective", "replacement", "failure", "lost_production"))
    np.testing.assert_allclose(breakdown, per["cost"])
    assert np.all((per["availability"] >= 0) & (per["availability"] <= 1))
    # with downtimes >= 1 step, down steps are the steps that cost lost production (4 per step)
    np.testing.assert_allclose((1 - per["availability"]) * per["steps"] * 4.0, per["cost_lost_production"])
    np.testing.assert_allclose(per["maintenance_actions"], per["replacements"] + per["corrective_steps"])
    d = stats.to_dict()
    assert d["mean_cost"] == stats.mean_cost and len(d["per_episode"]["cost"]) == 2
    import json

    json.dumps(d, allow_nan=False)
    # same seeds, same numbers; a callable env -> policy works too
    again = evaluate(lambda env: Oracle(env, 15.0), _oracle_env, seeds=[3, 4], progress=False)
    np.testing.assert_array_equal(again.per_episode["cost"], per["cost"])


def test_evaluate_counts_failures_and_maintenance():
    # run to failure on a fast-wearing machine: it fails, and the forced replacement stops it 20 steps
    from ea_gym.degradation import WearConfig

    fast = {c: WearConfig(rate=(0.2, 0.2), arrival=(0.0, 0.0)) for c in COMPONENTS}
    make = lambda: gym.make(  # noqa: E731
        "ea_gym/SpringMassDamper-v0", obs_mode="oracle", horizon=20, continue_after_failure=True, wear=fast
    )
    stats = evaluate(RunToFailure(), make, seeds=[0], progress=False)
    assert stats.failures >= 1 and stats.maintenance_actions == 0 and stats.availability < 1
    assert stats.cost_breakdown["failure"] == 400.0 * stats.failures
    saved = evaluate(Oracle(ACTIONS, 3.0), make, seeds=[0], progress=False)
    assert saved.failures == 0 and saved.maintenance_actions >= 1 and saved.per_episode["ignored_actions"][0] == 0
    assert math.isnan(saved.ci95[0]) and saved.to_dict()["ci95"] == [None, None]


def test_batched_evaluation_equals_one_episode_at_a_time():
    # the batched environment's episodes equal the single one's bit for bit, so every record must too:
    # a stateful policy (Periodic's round), failures with forced replacements, an uneven last batch
    from ea_gym.degradation import WearConfig

    fast = {c: WearConfig(rate=(0.05, 0.2), arrival=(0.0, 10.0)) for c in COMPONENTS}
    kwargs = dict(obs_mode="oracle", horizon=30, continue_after_failure=True, wear=fast)
    single = lambda: gym.make("ea_gym/SpringMassDamper-v0", **kwargs)  # noqa: E731
    vector = lambda n: gym.make_vec("ea_gym/SpringMassDamper-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs)  # noqa: E731
    seeds = [11, 12, 13, 14, 15]
    results = {}
    for name, policy in (("run", RunToFailure(ACTIONS)), ("periodic", Periodic(ACTIONS, 6.0)), ("oracle", Oracle(ACTIONS, 3.0, action="corrective"))):
        one = evaluate(policy, single, seeds, progress=False)
        batched = evaluate(policy, vector, seeds, progress=False, batch_size=2)
        assert batched.seeds.tolist() == seeds and batched.policy == one.policy
        for key, values in one.per_episode.items():
            np.testing.assert_array_equal(batched.per_episode[key], values, err_msg=f"{name}: {key}")
        assert one.per_episode["steps"].tolist() == [30] * 5
        results[name] = one.per_episode
    # every path was taken: failures, replacements while down (ignored orders), corrective steps
    assert results["run"]["failures"].sum() > 0
    assert results["periodic"]["replacements"].sum() > 0 and results["periodic"]["ignored_actions"].sum() == 0
    assert results["oracle"]["corrective_steps"].sum() > 0
    with pytest.raises(ValueError, match="batch_size"):
        evaluate(RunToFailure(ACTIONS), vector, seeds, progress=False, batch_size=0)
    same_step = lambda n: gym.make_vec(  # noqa: E731
        "ea_gym/SpringMassDamper-v0", num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode="SameStep", **kwargs
    )
    with pytest.raises(ValueError, match="must autoreset in AutoresetMode.NEXT_STEP"):
        evaluate(RunToFailure(ACTIONS), same_step, seeds, progress=False, batch_size=2)


def test_tune_picks_the_cheapest_value():
    best, table = tune(lambda t: Oracle(ACTIONS, t), [math.inf, 15.0], _oracle_env, seeds=[3], progress=False)
    assert [row["parameter"] for row in table] == [math.inf, 15.0]
    costs = [row["mean_cost"] for row in table]
    assert best == [math.inf, 15.0][int(np.argmin(costs))]


def test_mean_ci95():
    mean, low, high = mean_ci95([1.0, 3.0])
    assert mean == 2.0 and high - mean == pytest.approx(1.96 * math.sqrt(2) / math.sqrt(2))
    with pytest.raises(ValueError):
        mean_ci95([])


def test_policies_run_under_sb3_evaluate_policy_on_a_vec_env():
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import DummyVecEnv

    venv = DummyVecEnv([_oracle_env, _oracle_env])
    assert ActionMap.from_env(venv) == ActionMap(MEANINGS, COMPONENTS, CLASSES, "oracle", NOMINAL_POSITIONS, ("F", "m", "k", "b"))
    for policy in (RunToFailure(venv), Periodic(venv, 5.0), Oracle(venv, 10.0)):
        rewards, lengths = evaluate_policy(policy, venv, n_eval_episodes=2, return_episode_rewards=True, warn=False)
        assert lengths == [20, 20] and all(r <= 0 for r in rewards)
    periodic_rewards, _ = evaluate_policy(Periodic(venv, 5.0), venv, n_eval_episodes=2, return_episode_rewards=True, warn=False)
    assert max(periodic_rewards) <= -40.0  # it did replace something within 20 steps


def test_a_batched_evaluations_progress_bar_moves_with_every_step(monkeypatch):
    """The batch's episodes all end at the horizon together: counting ended episodes alone held the bar at 0 until the end."""
    import tqdm.auto

    shown: list[float] = []

    class Recorded(tqdm.auto.tqdm):
        def update(self, n=1):
            super().update(n)
            shown.append(self.n)

    monkeypatch.setattr(tqdm.auto, "tqdm", Recorded)
    vector = lambda n: gym.make_vec("ea_gym/SpringMassDamper-v0", num_envs=n, vectorization_mode="vector_entry_point",  # noqa: E731
                                    obs_mode="oracle", horizon=10, continue_after_failure=True)
    evaluate(RunToFailure(ACTIONS), vector, [0, 1, 2, 3], progress=True, batch_size=4)
    assert shown == pytest.approx([0.4 * step for step in range(1, 11)])
