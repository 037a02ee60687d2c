"""Pedestrian trajectory forecasting on ETH/UCY: data windows, baselines, metrics, evaluation.

* :mod:`navzoo.forecast.data` -- file loading, 8 + 12 step windows with neighbours, agent-centric
  frames, rotation augmentation, val and leave-one-scene-out splits;
* :mod:`navzoo.forecast.baselines` -- constant-velocity and social-force forecasters;
* :mod:`navzoo.forecast.metrics` -- minADE/minFDE, speed/acceleration/jerk EMDs, collision rate;
* :mod:`navzoo.forecast.evaluate` -- the forecaster registry and ``navzoo eval forecast``.

See ``docs/crowd.md``.
"""
