"""The research part of gwr_predictor: experiments, ablations, blends, benchmarks and soak runs.

Not installed with the ROS package; it runs from a source checkout (`scripts/env.sh` puts the
repository on the path), through `gwr-predictor experiment|bench|soak`. Importing it registers the
ablation and blend predictors (`research.predictors`) beside the product's in the one registry, so
experiments name them like any other predictor.
"""

from research import predictors as _predictors  # noqa: F401  (registers the research predictors)
