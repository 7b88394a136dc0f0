"""One file per scene (docs/model.md §8): cycle, impact, freefall."""
