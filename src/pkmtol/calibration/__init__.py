"""Stage 4, kinematic calibration: measurement plans, identification on exact kinematics, compensation."""
