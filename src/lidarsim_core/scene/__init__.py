"""What is scanned: triangle meshes with part labels, surface materials and the base class of
target models."""
