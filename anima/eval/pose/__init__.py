"""``anima eval pose``: the lifter on Human3.6M S9 and HumanEva (:mod:`.run`) and the protocols (:mod:`.metrics`)."""
