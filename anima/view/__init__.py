"""``anima view``: a local web page for any anima result (three.js, bundled at set-up; nothing fetched at run time)."""
