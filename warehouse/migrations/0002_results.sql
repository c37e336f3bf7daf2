-- Result marts written by 'ropeload run' and the calibration / discovery workflows.
CREATE TABLE position_summary (
    run_id VARCHAR NOT NULL,
    site VARCHAR NOT NULL,
    hoist VARCHAR NOT NULL,
    trip_id BIGINT,
    position VARCHAR NOT NULL,
    time_start_utc TIMESTAMPTZ,
    time_end_utc TIMESTAMPTZ,
    depth_m DOUBLE,
    tail_rope_length_m DOUBLE,
    tension_before1_n DOUBLE,
    tension_before2_n DOUBLE,
    tension_before3_n DOUBLE,
    tension_before4_n DOUBLE,
    tension_after1_n DOUBLE,
    tension_after2_n DOUBLE,
    tension_after3_n DOUBLE,
    tension_after4_n DOUBLE,
    load_before_n DOUBLE,
    load_after_n DOUBLE,
    expected_load_n DOUBLE,
    payload_kg DOUBLE,
    error_before_fraction DOUBLE,
    error_after_fraction DOUBLE,
    imbalance_after_fraction DOUBLE,
    samples BIGINT
);

CREATE TABLE trip_summary (
    run_id VARCHAR NOT NULL,
    site VARCHAR NOT NULL,
    hoist VARCHAR NOT NULL,
    trip_id BIGINT NOT NULL,
    direction VARCHAR,
    time_start_utc TIMESTAMPTZ,
    time_end_utc TIMESTAMPTZ,
    depth_start_m DOUBLE,
    depth_end_m DOUBLE,
    payload_kg DOUBLE,
    payload_spread_kg DOUBLE,
    max_load_n DOUBLE,
    max_imbalance_fraction DOUBLE
);

CREATE TABLE alarms (
    alarm_id VARCHAR NOT NULL,
    run_id VARCHAR NOT NULL,
    site VARCHAR NOT NULL,
    hoist VARCHAR NOT NULL,
    rule VARCHAR NOT NULL,
    rope INTEGER,
    start_utc TIMESTAMPTZ NOT NULL,
    end_utc TIMESTAMPTZ NOT NULL,
    peak_time_utc TIMESTAMPTZ,
    peak_value DOUBLE,
    threshold DOUBLE,
    unit VARCHAR,
    message VARCHAR,
    PRIMARY KEY (alarm_id)
);

CREATE TABLE friction_parameter_sets (
    parameter_set VARCHAR NOT NULL,
    created_at_utc TIMESTAMPTZ NOT NULL,
    source VARCHAR,
    bore_m DOUBLE,
    coulomb_n DOUBLE,
    coulomb_n_per_pa DOUBLE,
    static_n DOUBLE,
    static_n_per_pa DOUBLE,
    stribeck_speed_m_s DOUBLE,
    stribeck_speed_m_s_per_pa DOUBLE,
    viscous_n_s_m DOUBLE,
    viscous_n_s_m_per_pa DOUBLE,
    residual_rms MAP(VARCHAR, DOUBLE),
    inputs VARCHAR[],
    PRIMARY KEY (parameter_set)
);

CREATE TABLE sanity_checks (
    run_id VARCHAR NOT NULL,
    site VARCHAR NOT NULL,
    hoist VARCHAR NOT NULL,
    trip_id BIGINT NOT NULL,
    rms_gap_pa DOUBLE,
    noise_pa DOUBLE,
    passed BOOLEAN NOT NULL,
    message VARCHAR
);

CREATE TABLE discovery_findings (
    run_id VARCHAR NOT NULL,
    site VARCHAR NOT NULL,
    hoist VARCHAR NOT NULL,
    iteration INTEGER NOT NULL,
    period_start_utc TIMESTAMPTZ,
    period_end_utc TIMESTAMPTZ,
    effect VARCHAR NOT NULL,
    confidence DOUBLE,
    gap_before_pa DOUBLE,
    gap_after_pa DOUBLE,
    report_json VARCHAR NOT NULL
);
