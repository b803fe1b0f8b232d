"""What a `solved` promises about the trajectory the user gets: the error estimates
(:mod:`.estimates`: the replay, the bisection), the true motion the replay drives
(:mod:`.filippov`, the event-driven integrator, with its mode choice at an event by
:mod:`.complementarity` where it is large; :mod:`.model_system`, a model's own
x' ∈ g + B·Sgn(s); :mod:`.projection_replay`, the collocation replay without sign terms),
and the switch times (:mod:`.switches`)."""
