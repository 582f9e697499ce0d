"""Motion to files: the one writer of every motion output set (capture, text2face, gesture), the file
exports (ARKit CSV, GLB, BVH) and the framing of generated motion as a tracked sequence."""
