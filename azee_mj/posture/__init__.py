"""The parts of the posture solver (:mod:`azee_mj.ik` keeps the solving strategy).

- :mod:`~azee_mj.posture.problem`: the records (``IKProblem``, ``IKResult``, ``Residual``,
  ``Stop``: why a run stopped).
- :mod:`~azee_mj.posture.contract`: the records shared with the compiled core (block, term
  and tunables layouts) and the tunables' values.
- :mod:`~azee_mj.posture.plan`: a problem compiled for the core (row blocks, buffers).
- :mod:`~azee_mj.posture.scope`: the bodies and dofs a problem touches.
- :mod:`~azee_mj.posture.collision`: the geom pairs the core collides, and their clusters.
- :mod:`~azee_mj.posture.equalities`: placements mirrored as MuJoCo ``connect`` equalities.
- :mod:`~azee_mj.posture.starts`: where the restarts begin.
"""
