"""The ground floor of merge-irl: units, atomic files, run folders, the process guard, version and provenance, the table of moved import paths. Imports nothing of ours."""
