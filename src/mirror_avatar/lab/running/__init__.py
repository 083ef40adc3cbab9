"""Running lab sessions: the server, its API and pages, the clock's trials, schedules, LSL."""
