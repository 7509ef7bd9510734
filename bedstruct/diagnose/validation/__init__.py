"""How the diagnosis is validated: twins whose effect is withheld, scored against the truth.

The modules: ``design`` (what a validation twin's file measures), ``twins`` (how synthetic
twins are made and sized), ``validate`` (the validation on synthetic twins of the surrogate
or the embedded engine) with ``parallel`` (twins side by side in processes), ``records``
and ``scores`` (one record per diagnosed twin, the scores and goals); ``liggghts``,
``liggghts_twins`` and ``liggghts_law`` (twins made by LIGGGHTS, whose numerics are part of
the gap, and its liquid-bridge law); ``blind`` and ``blind_twins`` (the blind protocol:
truth drawn and sealed first, then diagnosed once); ``report`` (their reports and figures).
They use the method (``bedstruct.diagnose``'s other modules); the method never imports them.
The public names are in :mod:`bedstruct.diagnose`.
"""
