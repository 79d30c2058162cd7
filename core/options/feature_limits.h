// The per-photo feature budget (max_features): its one default and one range, shared by the
// option table (pipeline_options.cc, what clients may ask for) and SiftOptions::Check
// (core/feature/sift.h, what the extractor accepts), so the two cannot disagree.
// Constants only: including this needs no library.
#ifndef RECONDUIT_CORE_OPTIONS_FEATURE_LIMITS_H_
#define RECONDUIT_CORE_OPTIONS_FEATURE_LIMITS_H_

namespace reconduit {

// Default number of features kept per photo.
inline constexpr int kDefaultMaxFeatures = 8192;
// Accepted range of max_features, inclusive. Fewer than a few hundred features per photo are
// too few to register it; more than 65536 cost memory and matching time for no gain.
inline constexpr int kMinMaxFeatures = 256;
inline constexpr int kMaxMaxFeatures = 65536;
// Default of min_features: a photo with fewer SIFT candidates is detected again (sift.h).
// Every photo of fountain-P11, templeSparseRing and kermit has more (the fewest, a temple
// photo, about 1,080), so they are detected once.
inline constexpr int kDefaultMinFeatures = 1024;

}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIONS_FEATURE_LIMITS_H_
