"""How a study of trained wildfire policies trains each of them: the sizes and the learner its
config shares with the others (:class:`StudyTraining`), defined and checked once.

The studies' configs extend it (``TransferConfig``, on which the transfer variants and
``advantage-estimators`` build, ``BehaviourConfig`` and ``PenaltyConfig``) rather than hold it
as a part: its fields stay the configs' own, so that the flags (``--seeds``, ``--epochs``, ...),
the settings the sidecars record and the run folders are those of the configs before it. A config
gives its own defaults, and its own docstrings where they say more (the paper's value), by
declaring a field again. The bus sweeps and the GRU runs of the bus pictures do not extend it:
there the batch is the swept setting, or the released runner's fixed one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from repro.core.config import Validated
from repro.learn.config import DEFAULT_LEARNER, LEARNERS, TrainConfig, study_train_config


@dataclass(frozen=True)
class StudyTraining(Validated):
    """The training of every policy of a wildfire study."""

    seeds: int = 1
    """Policies trained from scratch per setting (training seeds seed, seed + 1, ...)."""
    epochs: int = 60
    """Training epochs per policy."""
    learner: str = DEFAULT_LEARNER
    """The named learner that trains every policy (``repro.learn.config.LEARNERS``)."""
    batch_decisions: int = 3000
    """Training decisions per epoch when the learner counts its batch in decisions (the released
    runner: 12,000)."""
    batch_episodes: int = 150
    """Training episodes per epoch when the learner counts its batch in episodes (the paper's
    table: 600 to 1,200)."""

    def validate(self) -> None:
        self.check(self.seeds >= 1, "seeds", "an integer >= 1")
        self.check(self.epochs >= 1, "epochs", "an integer >= 1")
        self.check(self.learner in LEARNERS, "learner", "one of " + ", ".join(LEARNERS))
        self.check(self.batch_decisions >= 1, "batch_decisions", "an integer >= 1")
        self.check(self.batch_episodes >= 1, "batch_episodes", "an integer >= 1")

    def train_config(self, scale: str, seed: int,
                     settings: tuple[tuple[str, Any], ...] = ()) -> TrainConfig:
        """The TrainConfig of the wildfire policy of training seed ``seed``: the learner's at
        ``scale``, its batch in the learner's unit, the study's epochs, then ``settings``
        ((field, value) pairs; :func:`repro.learn.config.study_train_config`)."""
        return study_train_config(scale, "wildfire", self.learner, self.batch_decisions,
                                  self.batch_episodes, settings, seed=seed, epochs=self.epochs)
