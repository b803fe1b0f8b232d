"""Every built-in model, registered under the `qdframe.models` entry points (pyproject.toml).

- ``paper.py``: the paper's Examples 7.1, 7.2 (``paper-7.1``, ``paper-7.2``), hand-written;
- ``paper_73.py``: Example 7.3 (``paper-7.3``, ``paper-7.3-reduced``), hand-written;
- ``paper_sets.py``: Examples 7.1–7.3 in the set language, not registered (the form to
  read; tests check it against the hand-written ones, which the registry serves);
- ``exact_friction.py``: Filippov problems with exact solutions (``block-stop-stick``, …);
- ``planar_friction.py``: friction in the plane and in space, in the set language
  (``orthotropic-puck``; isotropic friction by the vector sign Sgn(v1, v2): ``isotropic-puck``,
  ``isotropic-slide-3d``);
- ``user_friction.py``: friction models as users bring them (a pendulum with pivot friction, a
  two-block chain, a relay oscillator), with reference motions from their hand-written equations;
- ``identification.py``: problems whose end time or coefficient is unknown, with exact answers
  (``block-stopping-time``, ``relay-period``, ``block-friction-coefficient``, ``block-time-optimal``);
- ``bounded_input.py``: problems with a bounded input that the nosnoc peer states too
  (``coulomb-rest-to-rest``, ``sliding-mode-terminal``);
- ``optimal_control.py``: costs whose least value is not 0, a control bound and a terminal cost
  (``least-effort-block``, ``least-effort-bounded``, ``lq-terminal``), their exact optima in
  ``optimal_references.py``.
"""
