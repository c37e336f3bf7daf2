"""The physics of the hydraulic connection device: one function per paper equation.

Song et al. (``../shared/paper/``) model the four-cylinder rope attachment of a Koepe
hoist. Every equation the pipeline uses is written once, here: a numba scalar kernel
(what the compensation's per-sample loops and the simulations' integrators call) with
its vectorised wrapper beside it, or one function of floats, arrays and polars
expressions alike. ``transforms/`` (compensation, reconciliation, alarms, kinematics),
``sims/`` (device, rig, two-cylinder, replay) and ``pipelines/`` import these; none of
them writes an equation again. SI units throughout.

Equation index (paper equation -- function -- test)
====================================================

eq 1, piston force balance m_p x'' = T - p A - F
    quasi-static (m_p x'' -> 0) it is eq 2, :func:`physics.tension.rope_tension_n`;
    the dynamic form is a state equation of :mod:`sims.device`; solved for F on the
    friction rig by :func:`transforms.rig_friction.seal_friction_samples` --
    tests/physics/test_tension.py, tests/transforms/test_rig_friction.py
eq 2, T = p_chamber A + F
    :func:`physics.tension.rope_tension_n`, the piston areas
    :func:`~physics.tension.bore_area_m2`, :func:`~physics.tension.annulus_area_m2`
    -- tests/physics/test_tension.py; with T from the rope's spring (k = EA / L, not
    printed) and an elasto-plastic seal, one quasi-static step of a piston:
    :func:`physics.rope_spring.seal_on_rope_step`, :func:`~physics.rope_spring.
    head_rope_stiffness_n_m`; with Maxwell-slip elements :func:`~physics.rope_spring.
    elements_on_rope_step`, their virgin state :func:`physics.maxwell_slip.
    maxwell_slip_virgin`; a worn groove's payout (contract 4, ``groove_wear``)
    :func:`~physics.rope_spring.groove_payout_m` -- tests/transforms/test_stick_slip.py,
    tests/physics/test_rope_spring.py
eq 3-4 with Table 2, sum of T = (m_c + m_p + m_t(z)) (g + a)
    :func:`physics.tension.expected_load_n`, :func:`~physics.tension.tail_rope_mass_kg`,
    :func:`~physics.tension.tail_rope_length_m` -- tests/physics/test_tension.py
eq 5, continuity dV = V / beta dp
    beta with entrained air: :func:`physics.oil.effective_bulk_modulus` (scalar
    :func:`~physics.oil.effective_bulk_modulus_at`); the closed volume n A dx =
    V / beta dp: :func:`physics.closed_volume.common_mode_displacement` (per pascal:
    :func:`~physics.closed_volume.common_mode_per_pa`) --
    tests/physics/test_oil.py, tests/transforms/test_compensation_arrays.py
eq 6, Hagen-Poiseuille R = 128 mu l / (pi d^4)
    :func:`physics.branch_loss.laminar_resistance` -- tests/physics/test_branch_loss.py
eq 7, momentum of the oil column
    a state equation of :mod:`sims.device` and :mod:`sims.two_cylinder` --
    tests/sims/test_device.py, tests/sims/test_two_cylinder.py
eq 8-11, the two-cylinder second-order lag
    :func:`physics.two_cylinder.natural_frequency` (eq 9),
    :func:`~physics.two_cylinder.damping_ratio` (eq 10, corrected),
    :func:`~physics.two_cylinder.transfer_function` (eq 11, corrected) --
    tests/sims/test_two_cylinder.py
eq 12, Darcy friction factor lambda
    :func:`physics.branch_loss.darcy_friction_factor_at` (64/Re; turbulent by
    Colebrook, solved by Clamond, or Blasius) -- tests/physics/test_branch_loss.py
eq 12-14, branch loss (lambda l / d + xi) rho v |v| / 2
    :func:`physics.branch_loss.pipe_loss_pa`; the hoist's sensor branch (contract 1a):
    :func:`physics.sensor_branch.sensor_minus_chamber_at` --
    tests/physics/test_branch_loss.py
eq 15, LuGre (printed as "Leuven")
    :func:`physics.lugre.lugre_z_rate` and :func:`~physics.lugre.lugre_force_at` (the
    ODE), :func:`~physics.lugre.lugre_z_step` and :func:`~physics.lugre.lugre_force`
    (its exact step) -- tests/physics/test_friction.py
eq 16 and 18, the Stribeck curve and its bracket g(v)
    :func:`physics.friction_law.stribeck_g`, :func:`~physics.friction_law.stribeck_friction`
    -- tests/physics/test_friction.py
eq 17, Fc, Fs, vs, Kv linear in the chamber pressure
    :func:`physics.friction_law.friction_law_at`; fitted and compared with the printed
    law by :mod:`transforms.friction_fit` -- tests/physics/test_friction.py,
    tests/transforms/test_friction_fit.py
Leuven / Generalized Maxwell-Slip (not printed), presliding hysteresis
    :func:`physics.maxwell_slip.maxwell_slip_step` -- tests/physics/test_friction.py
ASTM D341 (not printed), viscosity from temperature
    :func:`physics.oil.kinematic_viscosity` -- tests/physics/test_oil.py
the trip rule (not printed), phase, direction, trip and shaft position
    :func:`physics.trip_rule.trip_label_codes`, :func:`~physics.trip_rule.position_codes`,
    the logger's gap segments :func:`~physics.trip_rule.segment_ids`
    -- tests/physics/test_trip_rule.py, tests/transforms/test_kinematics.py,
    tests/pipelines/test_sanity.py (the check names the run's trips)
the conveyance's motion (not printed), its speed where the log lacks it
    :func:`physics.conveyance.conveyance_speed` (the depth's derivative), the smoothed
    derivative every step takes :func:`~physics.conveyance.smoothed_derivative`
    -- tests/physics/test_conveyance.py, tests/discovery/test_segmentation.py
white noise from differences (not printed; von Neumann et al. 1941, the MAD's 1.4826)
    :func:`physics.white_noise.difference_noise_sigma` -- its doctests,
    tests/discovery/test_planning.py
the filters' designs (not printed; Savitzky and Golay 1964, Butterworth by the bilinear
transform), as scipy.signal designs them, without its import
    :func:`physics.filter_design.savgol_coeffs`, :func:`~physics.filter_design.savgol_filter`,
    :func:`~physics.filter_design.butter_lowpass_sos`, :func:`~physics.filter_design.sosfilt_zi`
    -- tests/physics/test_filter_design.py, tests/transforms/test_filtering.py

Errata are corrected where the equation is written: eq 10 and eq 11
(:mod:`physics.two_cylinder`), the name of eq 15 (:mod:`physics.lugre`), eq 17's
printed units (:func:`physics.friction_law.friction_law_at`).
``tests/test_outputs_unchanged.py`` shows that gathering the equations here left the
results of ``compensate``, the simulations, discovery and the demo unchanged.
"""
