"""Offline exact two-sphere solvers for dipolophoresis (run by ``scripts/generate_near_field_table.py``
and ``scripts/generate_near_field_stress_table.py``).

Two equal ideally polarisable spheres (thin, fully polarised double layers) in a uniform field, sphere 1
at the origin and sphere 2 at ``d z_hat``; units ``a = eta = eps = E0 = 1`` (velocities in
``U0 = eps a E0^2/eta``). Modules:

* :mod:`.electric` -- insulating-sphere potential by twin multipole expansion (``m = 0``, ``m = 1``);
  induced zeta with zero net charge;
* :mod:`.stokes` -- Lamb's solution about both centres, Galerkin on both surfaces: slip-driven,
  force-driven (mobility) and rigid (resistance) problems for ``m = 0`` and ``m = 1``;
* :mod:`.icep` -- force- and torque-free motion under the ICEP slip ``u_s = zeta grad_s(phi)``;
* :mod:`.dep` -- Maxwell force times the exact two-sphere mobility;
* :mod:`.solution` -- the six pair functions ``F_par, F_perp, F_x`` (ICEP, DEP) at one separation;
* :mod:`.stresslet` -- the ``m = 2`` Stokes problem, the exact stresslets (ICEP, DEP) and the DEP force;
* :mod:`.truncation`, :mod:`.legendre`, :mod:`.tabulation` -- truncation rule, Legendre functions and
  the table format / near-contact fit shared with :mod:`sim.dipolophoresis.near_field`;
* :mod:`.table_generator` -- the driver both generator scripts share (command line, resumable work
  file, loop over the nodes, common pieces of the table text).

Plain numpy/scipy: nothing here runs inside the time step.

References:
    D. Saintillan, Phys. Fluids 20, 067104 (2008); D. J. Jeffrey & Y. Onishi, J. Fluid Mech. 139, 261 (1984);
    S. Kim & S. J. Karrila, Microhydrodynamics (1991); T. M. Squires & M. Z. Bazant, J. Fluid Mech. 509,
    217 (2004) and 560, 65 (2006); L. D. Reed & F. A. Morrison, J. Colloid Interface Sci. 54, 117 (1976).
"""
