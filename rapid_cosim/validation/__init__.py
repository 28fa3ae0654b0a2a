"""Whether a model reproduces a recording: the per-test metrics of a measured and a
simulated curve (:mod:`.metrics`) and the tolerance bands they are judged against
(:mod:`.tolerances`). A decision, not a page: the validation report shows it, and the
fleet's playback of a record on file makes it, so it sits below both."""
