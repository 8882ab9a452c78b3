"""Physics: `World` (world.py), the compiled vehicle kernel (kernel.py), contact and sensors."""
