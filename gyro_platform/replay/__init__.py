"""replay — a rosbag2 bag through the simulator into an output bag (``gyro-platform replay``).

Holds the replay run (``loop``: ``ReplayConfig``, ``replay()``, the message loop, the summary),
the streamed output statistics (``stats``: ranges, drift-rate line fit, plot series) and the
command line (``command``: ``add_arguments``/``run``). Bag reading and writing are in ``io``
(``bag_reader``, ``bag_salvage``, ``bag_writer``), the gate → simulator → output grid in
``pipeline``. May import ``pipeline``, ``scenes``, ``engine``, ``io``, ``physics``, ``errors``.
"""
from ..errors import BagPathError, BagReadError, ReplayError
from ..io.bag_reader import InputBag
from ..pipeline import apply_decision, read_samples
from .command import NAMESPACE_RE, add_arguments, config_from_args, print_results, run
from .loop import DEFAULT_DIAGNOSTICS_RATE, DEFAULT_OUTPUT_RATE, ReplayConfig, replay, sidecar_paths

__all__ = ["replay", "ReplayConfig", "sidecar_paths", "add_arguments", "run", "config_from_args",
           "print_results", "NAMESPACE_RE", "DEFAULT_OUTPUT_RATE", "DEFAULT_DIAGNOSTICS_RATE",
           "BagReadError", "BagPathError", "ReplayError", "InputBag", "read_samples", "apply_decision"]
