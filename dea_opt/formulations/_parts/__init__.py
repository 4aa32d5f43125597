"""The formulations' shared parts, which are not formulations themselves (the registry names the
modules beside this package, one per formulation).

- ``system``: :class:`~dea_opt.formulations.SpringSystem` and
  :class:`~dea_opt.formulations.FormulationResult`, the arrays every small-kinematics formulation
  takes and the answer it gives, with the answers that need no solver;
- ``resistance``: the one test of which directions the springs resist ("unresisted");
- ``scaling``: the scaled variables every formulation solves in;
- ``crush``: the ``crushed`` verdict of a bounded law, proved from the layer's bound;
- ``options``: the option and capability declarations of the registry;
- ``sweeps``: Newton's fused passes over the springs;
- ``recentre``: solving on from an answer in its own scale;
- ``nlp_start``: the constrained NLP started from Newton's answer and multipliers;
- ``joint_newton`` and ``joint_ipopt``: a whole joint's inner solves.

Each module names the page of its math.
"""
