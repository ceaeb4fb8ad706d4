"""Independent reference implementations (numpy only) used as test oracles."""
