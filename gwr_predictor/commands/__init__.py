"""Sub-commands of `gwr-predictor`: each module has `configure(parser)` and `run(args) -> int`."""
