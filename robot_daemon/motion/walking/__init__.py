"""The omnidirectional walking engine: gait generator, leg inverse kinematics, parameters."""
