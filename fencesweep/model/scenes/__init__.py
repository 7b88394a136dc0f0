"""One file per scene (MODEL.md §8): cycle, impact, freefall."""
