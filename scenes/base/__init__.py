"""Pure helpers every layer may use (nothing of the project, never Mitsuba)."""
