-- Every calibrated value with its uncertainty: each eq 17 line's standard errors
-- (1 sigma, SI) and the covariance of its intercept and slope, keyed by the column
-- (`coulomb_n`, `coulomb_n_per_pa`, `coulomb_n_covariance`, ...). Sets landed before
-- (and those taken from a description, which states none) stay null.
ALTER TABLE friction_parameter_sets ADD COLUMN standard_error MAP(VARCHAR, DOUBLE);
