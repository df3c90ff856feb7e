"""robustrtk.estimation — estimators that know nothing about GNSS.

Modules
-------
:mod:`~robustrtk.estimation.state`
    :class:`StateLayout`, the :class:`State` protocol (what the engine needs from a state:
    Gaussian summary ``x``/``P``, layout, time, ``get``/``cov``, and the state operations
    ``add_ambiguities``, ``drop_ambiguities``, ``transform``, ``conditional_update``,
    ``constrain``, ``with_``), :class:`GaussianState` and :class:`UpdateResult`.
:mod:`~robustrtk.estimation.gaussian`
    The array kernels of those operations for bare ``(x, P)``.
:mod:`~robustrtk.estimation.models`
    Linear process models and the measurement-model protocol.
:mod:`~robustrtk.estimation.filters`
    EKF and UKF: a shared predictor, and an updater split into prior scaling,
    linearisation and the robust policy loop.
:mod:`~robustrtk.estimation.prior_scale`
    The prior-scaling hook (``PriorScale``; the innovation adaptive factor goes there).
:mod:`~robustrtk.estimation.adaptive`
    Yang's adaptive factors (innovation ratio; predicted-state discrepancy with the two-factor
    equivalent covariance, ``adaptive_update``) and the stationary/moving selector.
:mod:`~robustrtk.estimation.robust`
    Robust weighting policies usable by every filter.
:mod:`~robustrtk.estimation.registry`
    Filters, process models and policies by name; ``register_*`` adds new ones.
:mod:`~robustrtk.estimation.smoother`
    RTS smoother over layout changes.
:mod:`~robustrtk.estimation.particle`
    Particle filter: log-weights, systematic resampling under an ESS threshold,
    roughening, an exact proposal for linear sub-states (clocks), Gaussian summary.
:mod:`~robustrtk.estimation.coop`
    Cooperative positioning (Zhou et al. 2018): the location-time model, EKF / augmented
    UKF / particle filter / least squares behind one node interface, peer broadcasts and
    the range-variance inflation with covariance reset.

Dependencies point one way (``a → b``: a imports b): ``state → gaussian``,
``prior_scale → state``,
``filters → models, prior_scale, robust, state``, ``registry → filters, models, robust``,
``particle → models, state``, ``coop → filters, models, particle, state`` (and the rows of
:mod:`robustrtk.measurement.coop`);
``adaptive → filters, models, prior_scale, robust, state``;
nothing here imports ``pipeline`` or ``ambiguity``.
"""
