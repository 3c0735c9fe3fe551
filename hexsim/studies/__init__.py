"""The studies built on the engine (:mod:`hexsim.engine`), each using only its public face: the smoothness
metrics (:mod:`.metrics`) and what a passenger perceives (:mod:`.perception`), compensators compared
(:mod:`.comparison`), sweeps (:mod:`.sweeps`) and tuned (:mod:`.tuning`), motion cueing judged and tuned
(:mod:`.cueing`, :mod:`.cue_tuning`), the motion acceptance tests (:mod:`.acceptance`) and the oil-spring modes
(:mod:`.modes`)."""
