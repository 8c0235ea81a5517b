"""M-GAE for a learner of one's own: the public estimator (``macro_gae``), the SB3 rollout
buffer and route (``repro.learn.sb3``), and docs/own-learner.md's snippets, run as written."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from repro.envs.wildfire import WildfireConfig
from repro.learn.m_gae import advantage_paths, m_gae, macro_gae

pytestmark = pytest.mark.slow  # studies end to end, subprocesses: left out of make test-fast

torch = pytest.importorskip("torch")
DOC = Path(__file__).resolve().parents[1] / "docs" / "own-learner.md"
GAMMA = WildfireConfig().gamma


def random_paths(rng, n_paths):
    """(rewards, durations, values, last values) of ``n_paths`` random paths of random length."""
    lengths = rng.integers(1, 30, n_paths)
    return [(rng.normal(size=n), rng.exponential(3.0, n) + 1e-6, rng.normal(size=n),
             float(rng.normal())) for n in lengths]


def test_the_trainer_computes_what_macro_gae_computes_bit_for_bit(monkeypatch):
    """The trainer's own call during an epoch, path by path and as one time-major batch."""
    from repro.envs.wildfire import make_env
    from repro.learn import trainer as trainer_module
    from repro.learn.config import train_config

    seen = []

    def spy(estimator, rewards, durations, values, path_start, gamma, lam, last_values=None):
        out = advantage_paths(estimator, rewards, durations, values, path_start, gamma, lam,
                              last_values)
        seen.append((rewards, durations, values, path_start, gamma, lam, out))
        return out

    monkeypatch.setattr(trainer_module, "advantage_paths", spy)
    cfg = train_config("smoke", "wildfire", "authors", seed=4)
    trainer_module.Trainer(cfg, make_env(WildfireConfig())).run_epoch()
    rewards, durations, values, start, gamma, lam, (adv, ret) = seen[0]
    assert len(start) > 2  # several paths
    for a, b in zip(start[:-1], start[1:]):
        one_adv, one_ret = macro_gae(rewards[a:b], durations[a:b], values[a:b], 0.0, gamma, lam)
        assert np.array_equal(one_adv, adv[a:b]) and np.array_equal(one_ret, ret[a:b])
    # all paths in one column, each ending an episode
    ends = np.zeros(len(rewards), dtype=bool)
    ends[start[1:] - 1] = True
    col_adv, col_ret = macro_gae(rewards[:, None], durations[:, None], values[:, None], [1.5],
                                 gamma, lam, ends=ends[:, None])
    assert np.array_equal(col_adv[:, 0], adv) and np.array_equal(col_ret[:, 0], ret)


@pytest.mark.parametrize("seed", range(3))
def test_one_path_equals_the_papers_sums(seed):
    rng = np.random.default_rng(seed)
    for r, dt, v, last in random_paths(rng, 5):
        lam = float(rng.uniform(0, 4))  # lambda above 1 included
        got = macro_gae(r, dt, v, last, 0.05, lam)
        want = m_gae(r, dt, v, last, 0.05, lam)
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_a_time_major_batch_equals_its_paths_one_by_one(seed):
    """Columns of several paths each, cut by ``ends``; a column's last path is bootstrapped unless
    it ends there."""
    rng = np.random.default_rng(seed)
    n, m = 25, 4
    r, dt, v = rng.normal(size=(n, m)), rng.exponential(2.0, (n, m)), rng.normal(size=(n, m))
    ends = rng.random((n, m)) < 0.15
    ends[-1, 0] = True
    last = rng.normal(size=m)
    adv, ret = macro_gae(r, dt, v, last, 0.1, 2.0, ends=ends)
    for j in range(m):
        cuts = [0, *(np.flatnonzero(ends[:, j]) + 1)]
        cuts += [n] if cuts[-1] != n else []
        for a, b in zip(cuts[:-1], cuts[1:]):
            boot = 0.0 if ends[b - 1, j] else last[j]
            want = macro_gae(r[a:b, j], dt[a:b, j], v[a:b, j], boot, 0.1, 2.0)
            assert np.array_equal(adv[a:b, j], want[0]) and np.array_equal(ret[a:b, j], want[1])


def test_torch_in_gives_torch_out_of_the_same_dtype_and_values():
    rng = np.random.default_rng(1)
    r, dt, v, last = random_paths(rng, 1)[0]
    want = macro_gae(r, dt, v, last, 0.2, 1.5)
    for dtype in (torch.float32, torch.float64):
        adv, ret = macro_gae(torch.tensor(r, dtype=dtype), torch.tensor(dt, dtype=dtype),
                             torch.tensor(v, dtype=dtype), torch.tensor(last, dtype=dtype), 0.2,
                             1.5)
        assert isinstance(adv, torch.Tensor) and adv.dtype == dtype and ret.dtype == dtype
        assert adv.device == torch.device("cpu")
        if dtype == torch.float64:
            assert np.array_equal(adv.numpy(), want[0]) and np.array_equal(ret.numpy(), want[1])
        else:
            np.testing.assert_allclose(adv.numpy(), want[0], rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("change, name", [
    (dict(durations=[1.0, 0.0, 2.0]), "durations"),
    (dict(durations=[1.0, -1.0, 2.0]), "durations"),
    (dict(durations=[1.0, np.nan, 2.0]), "durations"),
    (dict(rewards=[1.0, np.nan, 2.0]), "rewards"),
    (dict(values=[1.0, 2.0]), "values"),
    (dict(durations=[1.0, 2.0]), "durations"),
    (dict(last_value=[1.0, 2.0]), "last_value"),
    (dict(gamma=0.0), "gamma"),
    (dict(lam=-1.0), "lam"),
    (dict(ends=[True, False]), "ends"),
])
def test_bad_input_is_refused_in_one_line_naming_it(change, name):
    args = dict(rewards=[1.0, 2.0, 3.0], durations=[1.0, 2.0, 3.0], values=[0.0, 0.5, 1.0],
                last_value=0.0, gamma=0.1, lam=1.0)
    args.update(change)
    with pytest.raises(ValueError) as err:
        macro_gae(**args)
    assert str(err.value).startswith(f"{name}: ") and "\n" not in str(err.value)


# --- the SB3 route ----------------------------------------------------------------------------


def ppo(parallel, lam, **kwargs):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure

    from repro.learn.sb3 import MGAERolloutBuffer, Spaces

    model = PPO("MlpPolicy", Spaces(parallel), n_steps=200, batch_size=50, n_epochs=2,
                policy_kwargs={"net_arch": [8]}, seed=3, device="cpu",
                rollout_buffer_class=MGAERolloutBuffer,
                rollout_buffer_kwargs=dict(gamma_rate=GAMMA, lam=lam),
                **kwargs)
    model.set_logger(configure(None, []))
    return model


@pytest.fixture
def wildfire():
    from repro.envs.wildfire.pettingzoo_env import parallel_env

    return parallel_env(WildfireConfig())


def test_the_buffer_computes_macro_gae_of_the_paths_it_holds(wildfire):
    from repro.learn.sb3 import collect_paths, fill_buffer

    model = ppo(wildfire, 2.0)
    paths = collect_paths(wildfire, model, 200, seed=5)
    model.rollout_buffer.compute_returns_and_advantage(*fill_buffer(model, paths))
    buf = model.rollout_buffer
    # the buffer's rows: the paths in order, the last one cut at the buffer's end
    rows, k = [], 0
    for p in paths:
        take = min(len(p["act"]), 200 - k)
        rows.append((p, take))
        k += take
        if k == 200:
            break
    k = 0
    for p, take in rows:
        cut = take < len(p["act"])
        want = macro_gae(np.float32(p["rew"][:take]), p["dur"][:take],
                         np.float32(p["value"][:take]),
                         np.float32(p["value"][take]) if cut else 0.0, GAMMA,
                         2.0)
        np.testing.assert_allclose(buf.advantages[k:k + take, 0], want[0], rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(buf.returns[k:k + take, 0], want[1], rtol=1e-5, atol=1e-6)
        k += take


def test_the_buffer_wants_durations(wildfire):
    model = ppo(wildfire, 1.0)
    with pytest.raises(ValueError, match="^durations: "):
        model.rollout_buffer.add(np.zeros((1, wildfire.observation_space("uav_0").shape[0])),
                                 np.array([[0]]), np.array([0.0]), np.array([True]),
                                 torch.zeros(1), torch.zeros(1))


@pytest.mark.parametrize("algorithm", ["PPO", "A2C"])
def test_sb3_trains_with_m_gae_through_the_parallel_env_and_repeats(wildfire, algorithm):
    """A tiny budget: SB3's own update runs on the M-GAE buffer, changes the policy, and a seed
    repeats it bit for bit."""
    sb3 = pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.logger import configure

    from repro.learn.sb3 import MGAERolloutBuffer, Spaces, train_update

    def run():
        kwargs = dict(batch_size=50, n_epochs=2) if algorithm == "PPO" else {}
        model = getattr(sb3, algorithm)(
            "MlpPolicy", Spaces(wildfire), n_steps=150, policy_kwargs={"net_arch": [8]}, seed=2,
            device="cpu", rollout_buffer_class=MGAERolloutBuffer,
            rollout_buffer_kwargs=dict(gamma_rate=GAMMA, lam=1.0), **kwargs)
        model.set_logger(configure(None, []))
        before = [p.detach().clone() for p in model.policy.parameters()]
        for u in range(2):
            paths, seconds = train_update(wildfire, model, seed=u)
            assert sum(len(p["act"]) for p in paths) >= 150 and set(seconds) == {
                "collect", "advantages", "train"}
        after = [p.detach().clone() for p in model.policy.parameters()]
        assert any(not torch.equal(a, b) for a, b in zip(before, after))
        return after

    assert all(torch.equal(a, b) for a, b in zip(run(), run()))


def test_the_docs_snippets_run():
    """Every python block of docs/own-learner.md, in order, in one namespace."""
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)
    assert len(blocks) >= 3
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, str(DOC), "exec"), namespace)


def test_several_envs_side_by_side_give_whole_paths_and_repeat():
    """Collection over several ParallelEnvs: every path is whole (a reward and a duration per
    decision, each duration > 0), the batch holds enough decisions, and a seed repeats it."""
    from repro.envs.bus import BusConfig
    from repro.envs.bus.pettingzoo_env import parallel_env
    from repro.learn.sb3 import collect_paths

    envs = [parallel_env(BusConfig()) for _ in range(3)]
    model = ppo(envs[0], 2.0)

    def batch():
        return collect_paths(envs, model, 300, seed=7)

    torch.manual_seed(0)
    paths = batch()
    assert sum(len(p["act"]) for p in paths) >= 300
    assert all(len(p["act"]) == len(p["rew"]) == len(p["dur"]) >= 1 for p in paths)
    assert min(min(p["dur"]) for p in paths) > 0
    torch.manual_seed(0)
    again = batch()
    assert [p["act"] for p in again] == [p["act"] for p in paths]


def test_the_study_resumes_to_the_same_bytes_and_refuses_other_settings(cli, tmp_path):
    """``beyond-sb3`` at smoke scale; run again it trains nothing and writes the same CSVs; a
    runs folder of other settings, and a budget that means nothing, are one-line errors."""
    folders = ["--runs-dir", str(tmp_path / "runs"), "--results-dir", str(tmp_path / "res"),
               "--figures-dir", str(tmp_path / "fig"), "--n-jobs", "1"]
    first = cli("beyond-sb3", "--scale", "smoke", *folders)
    assert first.returncode == 0, first.stderr
    runs = (tmp_path / "res" / "beyond_sb3.csv").read_bytes()
    summary = (tmp_path / "res" / "beyond_sb3_summary.csv").read_text()
    assert "sb3-ppo-mgae" in summary and (tmp_path / "fig" / "beyond_sb3.png").exists()
    again = cli("beyond-sb3", "--scale", "smoke", *folders)
    assert again.returncode == 0 and (tmp_path / "res" / "beyond_sb3.csv").read_bytes() == runs
    other = cli("beyond-sb3", "--scale", "smoke", "--updates", "3", *folders)
    assert other.returncode == 2 and "--runs-dir" in other.stderr
    bad = cli("beyond-sb3", "--scale", "smoke", "--updates", "0", *folders)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "updates" in bad.stderr


class EndsAtADecision:
    """A one-agent ParallelEnv whose episode ends at the instant of the agent's third decision
    (that decision's macro-action: duration 0, reward 0)."""

    possible_agents = ["a"]

    def __init__(self):
        from gymnasium import spaces

        self.space, self.actions = spaces.Box(-1, 1, (2,)), spaces.Discrete(2)

    def observation_space(self, agent):
        return self.space

    def action_space(self, agent):
        return self.actions

    def reset(self, seed=None, options=None):
        self.k, self.agents = 0, ["a"]
        return {"a": np.zeros(2, np.float32)}, {"a": {"decides": True, "duration": 0.0}}

    def step(self, actions):
        self.k += 1
        done = self.k == 3
        self.agents = [] if done else ["a"]
        return ({"a": np.full(2, self.k / 4, np.float32)}, {"a": 0.0 if done else 1.0},
                {"a": done}, {"a": False},
                {"a": {"decides": not done, "duration": 0.0 if done else 2.0}})


def test_a_decision_at_the_instant_the_episode_ends_is_left_out():
    from repro.learn.sb3 import collect_paths

    env = EndsAtADecision()
    model = ppo(env, 1.0)
    paths = collect_paths(env, model, 4, seed=0)
    assert [p["dur"] for p in paths] == [[2.0, 2.0], [2.0, 2.0]]
    assert all(len(p["obs"]) == len(p["act"]) == len(p["rew"]) == 2 for p in paths)
