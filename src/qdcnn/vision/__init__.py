"""Vision stage: shadow detectors, shadow removal, lane preprocessing, line grouping, metrics."""
