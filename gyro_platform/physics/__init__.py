"""physics — what the platform is and how it moves (ROS-free, numpy/numba).

Holds the parameters (``params``, NAV-1 defaults, validated, SI units), rotations, the generic
rigid-body tree (``tree``: kinematics, mass matrix, recursive Newton–Euler), the platform's
geometry and its three fidelities (``model``), the switchable effects (``effects``), the model
options (``options``: mode, fidelity, effects, integrator settings), the platform as an ODE
system over one input interval (``system``) and the single gimballed gyro (``gyro``). May import
only ``errors``: it knows nothing of integrators' bookkeeping, files or ROS.
"""
