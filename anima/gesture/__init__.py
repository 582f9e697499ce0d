"""Speech to gesture (seed 004 ch. 4-5). So far: the controllable motion-matching k-NN search (Algorithm 1)
on (audio, motion) windows of the dataset builder."""
