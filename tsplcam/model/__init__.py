"""Model stage: T-meshes, blending functions, extraordinary regions, patches and their evaluation."""
