"""The registry of parameter estimators: the name ``PHMConfig.estimator_kind`` gives -> the stages it builds.

An estimator kind builds, for a chain, a ``ParameterEstimator`` (:mod:`~ea_gym.phm.estimation`: it
follows each degradable parameter as if it alone were faulty and weighs the hypotheses) and the
``PrognosisStage`` (:mod:`~ea_gym.phm.prognosis`) that carries its estimates to the safe limits,
with the weights of the isolation's other evidence beside its own (:class:`EstimationStages`). Each
estimator's module registers its builder with one line; the built-in ones,

* "tracking" (:mod:`~ea_gym.phm.tracking`): a Kalman filter per hypothesis tracking the parameter
  and its drift, the drift carried to the limits with its covariance (``DriftPrognosis``);
* "ea_inversion" (:mod:`~ea_gym.phm.inversion_estimator`): the paper's EA inversion with a causal
  median, its recent estimates' trend extrapolated (``TrendPrognosis``);
* "joint" (:mod:`~ea_gym.phm.joint`): one Kalman filter per system over the states, every degradable
  parameter and its drift at once, each part's degrading probability beside (``DriftPrognosis``),

register when ``ea_gym.phm`` is imported.

Adding an estimator: one module with the estimator (any class with ``ParameterEstimator``'s methods
and attributes) and one registration line on its builder. A particle filter, say::

    # my_package/particle_filter.py
    from ea_gym.phm import DriftPrognosis, EstimationStages, register_estimator

    class ParticleFilter:  # each degradable parameter and its drift followed with particles
        def __init__(self, model, timing, n_systems): ...
        # ParameterEstimator's attributes and methods: degradable, lag, warmup_steps, reset,
        # record_adjustment, restart, update; for DriftPrognosis, diffusion (D,); for the model-fit
        # test, innovations() (ea_gym.phm.fit.InnovationSource)

    @register_estimator("particle_filter")
    def particle_filter_stages(model, monitor, config, n_systems):
        estimator = ParticleFilter(model, config.timing, n_systems)
        prognosis = DriftPrognosis(model, estimator.degradable, config.extrapolation, estimator.diffusion, n_systems)
        return EstimationStages(estimator, prognosis, innovations=estimator)

Once the module is imported, ``PHMConfig(estimator_kind="particle_filter")`` builds chains (and
environments: ``gym.make(..., phm=PHMConfig(estimator_kind="particle_filter"))``) with it. The
builder gets the model, the chain's monitor, the whole ``PHMConfig`` (its ``timing`` and whichever
section the estimator reads) and the batch size N.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ea_gym.diagnosis.monitor import Monitor
from ea_gym.models import SystemModel
from ea_gym.phm.config import PHMConfig
from ea_gym.phm.estimation import ParameterEstimator
from ea_gym.phm.fit import InnovationSource
from ea_gym.phm.isolation import EvidenceWeights
from ea_gym.phm.prognosis import PrognosisStage


@dataclass(frozen=True)
class EstimationStages:
    """An estimator kind's stages: the parameter estimator, the prognosis that reads its output, how
    much the isolation's other evidence (network, energy balance) counts beside its evidence, and where
    the model-fit test (:mod:`~ea_gym.phm.fit`) reads the innovations (usually the estimator; None: it has
    none, and the fit is not tested)."""

    estimator: ParameterEstimator
    prognosis: PrognosisStage
    weights: EvidenceWeights = EvidenceWeights()
    innovations: InnovationSource | None = None


#: builds an estimator kind's stages from the model, the chain's monitor, the chain's settings and N
StagesBuilder = Callable[[SystemModel, Monitor, PHMConfig, int], EstimationStages]

#: estimator kind -> its stages' builder; filled by ``register_estimator``
ESTIMATORS: dict[str, StagesBuilder] = {}


def register_estimator(name: str) -> Callable[[StagesBuilder], StagesBuilder]:
    """Decorator registering a stages builder under ``name`` (the value of ``PHMConfig.estimator_kind`` that
    selects it); returns the builder unchanged. A name registered twice is an error."""

    def register(builder: StagesBuilder) -> StagesBuilder:
        if name in ESTIMATORS:
            raise ValueError(f"an estimator named {name!r} is already registered")
        ESTIMATORS[name] = builder
        return builder

    return register


def registered_estimators() -> tuple[str, ...]:
    """The registered estimator kinds, sorted."""
    return tuple(sorted(ESTIMATORS))


def make_stages(model: SystemModel, monitor: Monitor, config: PHMConfig, n_systems: int) -> EstimationStages:
    """The stages of the estimator kind ``config.estimator_kind``; a ValueError naming the registered kinds
    when it is not one of them."""
    builder = ESTIMATORS.get(config.estimator_kind)
    if builder is None:
        raise ValueError(
            f"estimator_kind: no estimator named {config.estimator_kind!r} is registered; registered: {', '.join(registered_estimators())} "
            "(see ea_gym.phm.registry to add one)"
        )
    return builder(model, monitor, config, n_systems)
