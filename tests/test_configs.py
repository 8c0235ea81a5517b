"""Every config validates itself on construction: no config with a bad value exists."""

from __future__ import annotations

import dataclasses

import pytest

from repro.core.errors import UsageError
from repro.envs.bus import BusConfig
from repro.envs.toy import ToyConfig
from repro.envs.wildfire import WildfireConfig
from repro.learn.config import TrainConfig
from repro.studies.races.race import RaceConfig
from repro.studies.transfer.study import TransferConfig


@pytest.mark.parametrize("make, param", [
    (lambda: WildfireConfig(n_agents=-3), "--n-agents"),
    (lambda: dataclasses.replace(WildfireConfig(), t_health=0.0), "--t-health"),
    (lambda: BusConfig(n_buses=0), "--n-buses"),
    (lambda: ToyConfig(n_agents=0), "--n-agents"),
    (lambda: TrainConfig(epochs=0), "--epochs"),
    (lambda: RaceConfig(n_sets=0), "--n-sets"),
    (lambda: TransferConfig(seeds=0), "--seeds"),
])
def test_a_bad_value_cannot_be_constructed(make, param):
    with pytest.raises(UsageError, match=param):
        make()


def _study_configs() -> list[type]:
    """Every config class of the studies (repro.studies): dataclasses that validate and have
    their sizes by scale (a bare base like bench.common.BenchConfig has none)."""
    import importlib
    import pkgutil

    import repro.studies as pkg
    from repro.core.config import Validated

    found = set()
    for info in pkgutil.walk_packages(pkg.__path__, prefix=f"{pkg.__name__}."):
        module = importlib.import_module(info.name)
        found |= {c for c in vars(module).values() if isinstance(c, type)
                  and issubclass(c, Validated) and dataclasses.is_dataclass(c)
                  and hasattr(c, "SCALES")
                  and c.__module__.startswith(pkg.__name__)}
    return sorted(found, key=lambda c: (c.__module__, c.__qualname__))


@pytest.mark.parametrize("cls", _study_configs(), ids=lambda c: f"{c.__module__}.{c.__name__}")
def test_a_studys_refusal_names_the_flag_of_the_field_it_refuses(cls):
    """A bad number in any field of a study's config is refused naming that field's flag (the
    flags are generated from the fields), never another spelling."""
    from repro.core.config import flag, for_scale

    base, tried = for_scale(cls, "quick"), 0
    for field in dataclasses.fields(cls):
        value = getattr(base, field.name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        try:
            dataclasses.replace(base, **{field.name: -10**6})
        except UsageError as err:
            tried += 1
            assert err.param == flag(field.name), (field.name, str(err))
    assert tried, f"{cls.__name__}: no numeric field is checked"


def test_the_wildfire_studies_of_trained_policies_share_one_training_definition():
    """Transfer, behaviour and penalty configs extend StudyTraining: its fields first and in its
    order (the order their sidecars record), its docstrings where a config says no more, and its
    checks, which name the flag."""
    from repro.core.config import field_docs
    from repro.studies.kit.training import StudyTraining
    from repro.studies.wildfire.penalty import PenaltyConfig
    from repro.studies.wildfire.study import BehaviourConfig

    shared = [f.name for f in dataclasses.fields(StudyTraining)]
    assert shared == ["seeds", "epochs", "learner", "batch_decisions", "batch_episodes"]
    for cls in (TransferConfig, BehaviourConfig, PenaltyConfig):
        assert issubclass(cls, StudyTraining)
        assert [f.name for f in dataclasses.fields(cls)][:len(shared)] == shared
        for name in ("learner", "batch_decisions", "batch_episodes"):
            assert field_docs(cls)[name] == field_docs(StudyTraining)[name], (cls, name)
        with pytest.raises(UsageError, match="--batch-decisions"):
            cls(batch_decisions=0)
    assert BehaviourConfig().batch_episodes == 200 and TransferConfig().batch_episodes == 150
