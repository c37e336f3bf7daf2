"""What the paper prints: its two tables and the numbers of its text, as printed.

Song et al., *Research on Dynamic Characteristics and Compensation of Wire Rope Tension
and Load Measurement Based on Hydraulic Connection Device*. The tables are kept here
(not read from a file) so that ``ropeload paper`` runs from any checkout; the test
suite checks them against the CSV copies beside the repository when those exist.
Units are the paper's (MPa, kN, t, mm); conversion to SI happens where they are used.
Errata are those of the reading notes (``../shared/paper/NOTES.md``).
"""

from __future__ import annotations

import polars as pl

__all__ = [
    "SECTION_2_2",
    "SECTION_3_1",
    "TEXT_PITHEAD_BEFORE_KN",
    "TEXT_PITHEAD_GAIN_PERCENT",
    "table1",
    "table2",
]

_TABLE1 = {
    "oil_pressure_mpa": [2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12],
    "coulomb_friction": [
        0.0799, 0.1095, 0.1331, 0.1557, 0.1813, 0.2116, 0.2368, 0.2584, 0.2963, 0.3356, 0.3192,
    ],
    "max_static_friction": [
        0.1771, 0.1993, 0.2360, 0.2578, 0.2770, 0.2983, 0.3279, 0.3586, 0.3809, 0.4093, 0.4277,
    ],
    "stribeck_speed": [
        7.8386, 6.1813, 6.7047, 6.0063, 5.9152, 5.5787, 5.2612, 4.7855, 4.3099, 4.1943, 3.4387,
    ],
    "viscous_coefficient": [
        0.0013, 0.0014, 0.0015, 0.0015, 0.0017, 0.0017, 0.0017, 0.0018, 0.0019, 0.0019, 0.0020,
    ],
}  # fmt: skip

_TABLE2 = {
    "position": ["pithead", "middle", "bottom"],
    "tail_rope_length_m": [620, 300, 20],
    "before_kn_1": [34.7, 29.6, 16.8],
    "before_kn_2": [35.1, 26.8, 17.7],
    "before_kn_3": [35.8, 28.3, 16.9],
    "before_kn_4": [36.2, 26.5, 16.7],
    "after_kn_1": [37.8, 29.7, 21.1],
    "after_kn_2": [39.6, 30.6, 20.0],
    "after_kn_3": [39.5, 29.3, 20.4],
    "after_kn_4": [38.7, 29.1, 21.6],
    "sum_before_kn": [141.8, 111.2, 68.1],
    "sum_after_kn": [155.6, 118.7, 83.1],
    "total_mass_t": [15.888, 11.92, 8.448],
    "tail_rope_mass_t": [7.688, 3.72, 0.248],
}

#: Section 5.2's text: "the tension at pithead before and after compensation is
#: 145.2 kN and 155.6 kN, and the compensation rate reaches 9.7 %". Table 2's four
#: ropes sum to 141.8 kN, and only 141.8 kN gives 9.7 %: 145.2 is an erratum.
TEXT_PITHEAD_BEFORE_KN = 145.2
TEXT_PITHEAD_GAIN_PERCENT = 9.7

#: Section 2.2, the two-cylinder simulation: constants as printed (the bulk modulus
#: is not given). Eq 10 and eq 11 have errata (NOTES.md): eq 10 prints ``pi d beta``
#: under the root (``pi beta rho`` follows from eq 8), eq 11 prints ``1/omega_n`` as
#: the s^2 coefficient (``1/omega_n^2``).
SECTION_2_2 = {
    "density_kg_m3": 900.0,
    "kinematic_viscosity_mm2_s": 46.0,
    "dynamic_viscosity_kg_m_s": 0.0414,
    "piston_diameter_mm": 80.0,
    "cylinder_length_mm": 800.0,
    "pipe_diameter_mm": 6.0,
    "pipe_length_mm": 1000.0,
}

#: Section 3.1, the single-cylinder simulation (Fig. 4-5, 7): pump 12 MPa rated,
#: 20 L/min; cylinder 100 x 60 x 1000 mm; loads 11..1 MPa by the overflow valve; the
#: loss 0.36 MPa at every load; at 11 MPa "the maximum fluctuation pressure is
#: 11.86 MPa during 0.2 s and the pressure is stable at 11.36 MPa after 0.3 s";
#: Fig. 7: at 10 MPa and 20/15/10/5 L/min the loss varies with flow, the fluctuation
#: amplitude is proportional to the flow and the time to balance inversely so.
SECTION_3_1 = {
    "pump_pressure_mpa": 12.0,
    "pump_flow_l_min": 20.0,
    "bore_mm": 100.0,
    "rod_mm": 60.0,
    "stroke_mm": 1000.0,
    "load_pressures_mpa": (11.0, 9.0, 7.0, 5.0, 3.0, 1.0),
    "loss_mpa": 0.36,
    "peak_mpa": 11.86,
    "peak_time_s": 0.2,
    "steady_mpa": 11.36,
    "steady_after_s": 0.3,
    "flow_load_mpa": 10.0,
    "flows_l_min": (20.0, 15.0, 10.0, 5.0),
}


def table1() -> pl.DataFrame:
    """Paper Table 1 (friction parameters per oil pressure), columns as
    :data:`transforms.friction_fit.TABLE1_COLUMNS`; no units in the paper."""
    return pl.DataFrame(_TABLE1).with_columns(pl.col("oil_pressure_mpa").cast(pl.Int64))


def table2() -> pl.DataFrame:
    """Paper Table 2 (field test), the columns of ``table2_field_test.csv`` (kN, t, m)."""
    return pl.DataFrame(_TABLE2)
