"""What a run produces: the point cloud of a frame with its metadata, and ground-truth pose
records."""
