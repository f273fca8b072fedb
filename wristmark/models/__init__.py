"""Robot description: closed-form kinematics, Pinocchio model, actuation map, the true plant."""
