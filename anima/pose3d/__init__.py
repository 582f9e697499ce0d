"""Monocular 3D body pose with weak supervision (seed 004 ch. 3, Habibie et al. CVPR 2019) as a lifter on
MediaPipe's 2D evidence: joint sets, data, the network, training and evaluation."""
