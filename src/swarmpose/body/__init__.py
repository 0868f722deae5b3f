"""The body model: spec files, subjects and their measurements, kinematics, priors and inverse kinematics."""
