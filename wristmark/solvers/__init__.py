"""CasADi formulations: stereo pose solve and controllers."""
