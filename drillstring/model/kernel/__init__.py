"""Array-level numerics of the drill-string model (numba-compilable, plain Python otherwise).

Layout of the arrays shared by the kernel modules and :class:`drillstring.model.engine.Engine`:

* ``P`` parameters (``P_*`` indices), ``O`` options (``O_*``), ``C`` control law (``C_*``);
* ``Y`` state ``[U, V, Phi, W, Theta, Wt]`` in total scaled coordinates (NOTES.md section 1);
* ``X`` float scalars (``X_*``), ``I`` integer scalars (``I_*``), ``D`` diagnostics (``D_*``);
* ``H`` history nodes, rows ``tau, U, V, Phi, W``, valid columns ``I[I_HSTART]:I[I_HEND]``;
* ``E`` event log rows ``tau, kind, from_mode, to_mode, V, gstar``.
"""
