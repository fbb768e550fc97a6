"""The package's one exception base.

Every error class of gwr_predictor (and of its nodes) derives from `GwrPredictorError`, so a caller
(the `gwr-predictor` command line, a node, a script) can catch everything the package raises on
purpose in one `except` and report it in one line, while bugs (TypeError, KeyError of our own code...)
still surface with a traceback.

Below it, one class per subpackage, in its `errors.py` (or its central module): `data.DataError`,
`learning.LearningError`, `default_predictor.DefaultPredictorError`, `predictors.PredictorError`,
`evaluation.EvaluationError`, `robot.RobotError`, `pipeline.PipelineError`, the commands'
`RecordingError`, the nodes' `NodeFatalError`; and `parameters.spec.ParameterError` for a setting out
of its range. A case a caller must tell apart is an attribute of the class, not a class of its own
(`PipelineError.reason == "too_large"`, `LearningError.kind_mismatch`, `.locked`, `.source`). Older
names (`DataError`, `CheckpointError`, `BagError`, ...) are module aliases of their
subpackage's class. The classes keep the built-in bases callers catch (ValueError; RuntimeError too
where the bags, videos, simulator and experiment outputs raised one).
"""


class GwrPredictorError(Exception):
    """Base of every error gwr_predictor raises on purpose; the message names the file/field and what is wrong."""
