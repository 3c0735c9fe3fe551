"""What a run leaves behind: figures (:mod:`.plotting`, matplotlib), rerun recordings (:mod:`.rerun_log`),
the summary and JSON (:mod:`.report`), and logs in the measurement-log format (:mod:`.logio`)."""
