"""The compiled kernel of the model: array-level numerics in the subset numba compiles.

``state`` names every array and entry (:class:`~drillstring.model.kernel.state.KernelState`);
``equations`` is the right-hand side (11)-(13), ``filippov`` the contact law (17), ``hermite``
the history and the delay (14), ``events`` the event tables, ``stepper`` the RK4 step with
located events. ``docs/model.md`` describes the model they compute.
"""
