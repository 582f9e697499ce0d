"""``anima eval text2face``: tables 7.1-7.3 and the runner (:mod:`.run`), the metrics (:mod:`.metrics`), the
R-precision evaluator (:mod:`.evaluator`), the prompt suites (:mod:`.prompts`) and the independent judge that
reads generated motion back from its own render (:mod:`.judge`, :mod:`.judge_render`)."""
