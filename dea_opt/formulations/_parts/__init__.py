"""The formulations' private parts: the option and capability declarations of the registry
(``options``) and the array-level pieces of finite kinematics (``finite_geometry``: rotations,
targets, gaps; ``finite_system``: forces, residual, tangent; ``finite_newton`` and
``finite_ipopt``: the inner solves). They are not formulations: the registry names the modules
beside this package."""
