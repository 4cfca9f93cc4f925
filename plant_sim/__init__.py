"""The rig's physics: model, integrator, input profiles, degradation, noise, effects (pure)."""
