"""``anima eval gesture``: metrics (:mod:`.metrics`), the k-NN rows and the runner (:mod:`.run`), the learned
models' rows (:mod:`.learned`) and lip sync on FaceGood's recordings (:mod:`.facegood`)."""
