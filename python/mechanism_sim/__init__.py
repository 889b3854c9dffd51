"""mechanism_sim: URDF mechanisms with closed loops, from Python (doc/python.md).

    import mechanism_sim
    m = mechanism_sim.load("urdf/four_bar.urdf")
    m.advance(1.0, 1e-3)
    m.time(), m.positions(), m.violation()

The compiled part is mechanism_sim._mechanism_sim (src/python/module.cpp); this package
also holds the node's messages (mechanism_sim.msg, mechanism_sim.srv) and the design
sweeps of scripts/sweep (mechanism_sim.sweep, doc/sweeps.md).
"""
# The package spans the source tree (this file) and the devel space (the compiled module,
# the messages): whichever of them a process finds first on sys.path, it sees both.
__path__ = __import__("pkgutil").extend_path(__path__, __name__)

from ._mechanism_sim import (  # noqa: F401
    Error,
    LoadError,
    Model,
    ModelError,
    SimulationError,
    Snapshot,
    StepFailure,
    UsageError,
    load,
    load_string,
)

__all__ = ["Error", "LoadError", "Model", "ModelError", "SimulationError", "Snapshot", "StepFailure",
           "UsageError", "load", "load_string"]
