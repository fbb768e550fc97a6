"""gwr_predictor: online sensorimotor prediction with Growing When Required networks.

The library is pure Python + numpy (no rclpy), one subpackage per concern, in the order data flows:

- `data`: demonstrator, skeleton files, median of 3, the 8 Nao arm angles;
- `learning`: the paper's GWR -> Predictive GWR -> hierarchy, parameters, checkpoints;
- `default_predictor`: the default predictor, beyond the paper (`make_default`, composed in `default.py`);
- `predictors`: the baselines the learners must beat;
- `registry`: every predictor by name, above the paper's model and the default (`make_predictor`);
- `evaluation`: the online evaluation loop, metrics and result tables;
- `robot`: Nao kinematics/URDF, PyBullet simulator, delayed arm, delay compensator;
- `pipeline`: message conventions, MCAP bags, run reports and latency (ROS-free);
- `commands`: the `gwr-predictor` command line over all of the above;

and below them all, what every part shares: `joints` (the arm angles' and the skeleton's joints and
rates), `files` (the rules for files and paths a user names), `parameters` (`ParamSpec`).

Experiments, ablations, blends and benchmarks live in the repository's research/ folder, which is
not installed: `gwr-predictor experiment|bench|soak` run them from a source checkout.

ROS nodes live in `gwr_predictor.nodes` and only convert messages. Every predictor follows
`Predictor` (`learning/protocol.py`); every error the package raises derives from `GwrPredictorError`.

Start here: `make_default()` (the default predictor, `make_predictor("gwr_experts")`; the paper's model
is `make_predictor("hierarchy")`, every name in `predictor_names()`), `compare_online(models,
demo_angle_sequences(...))`, `load_predictor(name, checkpoint)`.
"""

from gwr_predictor._exports import lazy_exports

__version__ = "0.1.0"

_EXPORTS = {
    "Hierarchy": "learning.hierarchy",
    "HierarchyParams": "learning.params",
    "GWRParams": "learning.params",
    "GWR": "learning.gwr",
    "PredictiveGWR": "learning.predictive_gwr",
    "HoldLast": "predictors.baselines",
    "make_default": "default_predictor",
    "GatedPredictor": "default_predictor.gate",
    "LocalLinearPredictor": "default_predictor.predictor",
    "make_predictor": "registry",
    "load_predictor": "registry",
    "compare_online": "evaluation.online",
    "skeleton_to_angles": "data.angles",
    "extract_angles": "data.extraction",
    "ParamSpec": "parameters.spec",
    "load_skeleton": "data.skeleton_files",
    "ARM_JOINTS": "robot.nao",
    "GwrPredictorError": "errors",
    "Predictor": "learning.protocol",
    "register": "registry",
    "predictor_names": "registry",
    "demo_angle_sequences": "data.datasets",
}
__all__ = ["__version__", *sorted(_EXPORTS)]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
