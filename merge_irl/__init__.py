"""The ground floor of merge-irl: units, atomic files, run folders, the process guard, version and provenance. Imports nothing of ours."""
