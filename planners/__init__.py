"""Classical baselines: clustering, tours, 3D paths, power split, bounds (built on ``swiptopt``'s model)."""
