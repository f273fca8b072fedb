"""Computer vision for stereo: cameras, marker, image synthesis, corner detection, tracking."""
