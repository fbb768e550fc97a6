"""The package's one exception base.

Every error class of gwr_predictor (and of its nodes) derives from `GwrPredictorError`, so a caller
(the `gwr-predictor` command line, a node, a script) can catch everything the package raises on
purpose in one `except` and report it in one line, while bugs (TypeError, KeyError of our own code...)
still surface with a traceback.

Below it, one class per subpackage, in its `errors.py` (or its central module): `data.DataError`,
`learning.LearningError`, `default_predictor.DefaultPredictorError`, `predictors.PredictorError`,
`evaluation.EvaluationError`, `robot.RobotError`, `pipeline.PipelineError`, `commands.CommandError`,
the nodes' `NodeFatalError`; and `parameters.spec.ParameterError` for a setting out of its range. A
case a caller must tell apart is an attribute of the class, not a class of its own
(`PipelineError.reason == "too_large"`, `LearningError.kind_mismatch`, `.locked`, `.source`). The
classes also derive from the built-in class a caller of such a function would catch anyway (ValueError
for bad values and files; RuntimeError too for bags, videos, the simulator and experiment outputs).
"""


class GwrPredictorError(Exception):
    """Base of every error gwr_predictor raises on purpose; the message names the file/field and what is wrong."""
