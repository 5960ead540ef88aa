"""The engines: the contract every adapter implements (base), the registry of entry points,
shared kinematics, and one package per engine."""
