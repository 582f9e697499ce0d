"""anima live: everything real-time. A source (camera, file, stream: :mod:`anima.live.sources`) is tracked
frame by frame (:mod:`anima.live.tracker`) and each frame goes to the outputs (:mod:`anima.live.sinks`: the
browser page, Live Link Face, the VMC protocol), optionally recorded as a take (:mod:`anima.live.take`); the
command is :func:`anima.live.run.run` with a :class:`anima.live.config.LiveConfig`. Live re-enactment
(``anima reenact --live``) reads the same sources (:mod:`anima.live.reenact`)."""
