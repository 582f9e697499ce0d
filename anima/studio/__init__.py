"""``anima studio``: a local web app where a person drops a video (or a speech file, or types a sentence), watches
the job's progress and takes the animation home (docs/studio.md). The server and its API: :mod:`.server`; the
jobs, run one at a time by anima's own commands: :mod:`.jobs`; uploads and their checks: :mod:`.uploads`."""
