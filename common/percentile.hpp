// Percentiles of a sample (step times, loop periods, round trips): one definition for every
// report, so that a median in metrics.json, performance.csv and the bridge's summary mean the
// same thing.
#pragma once

#include <vector>

namespace incise::common {

// The q-quantile (q in [0, 1]) by linear interpolation between the two closest ranks of the
// sorted values (numpy's default); 0 for an empty sample.
double percentile(std::vector<double> values, double q);

// percentile(values, 0.5): for an even count, the midpoint of the two middle values.
double median(std::vector<double> values);

}  // namespace incise::common
