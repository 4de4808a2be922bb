"""oracle.scoring.ci: how a score is judged in CI: gates, baselines, profiles, JUnit and
summaries."""
