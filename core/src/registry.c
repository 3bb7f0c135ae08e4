/* Every denoiser and filter the library offers, in the order tools list them.
 *
 * The array is weak so that a test build can link a registry with one
 * method more (tests/gain: a method added as docs/adding-a-method.md says,
 * to check it reaches every front): that registry defines
 * EW_EXTRA_OP_TYPES and includes this file, and its strong definition wins. */
#include "src/op.h"

extern const ew_op_type ew_denoise_bgrid, ew_denoise_auto;
extern const ew_op_type ew_denoise_nbg;
extern const ew_op_type ew_denoise_kpcn;
extern const ew_op_type ew_filter_temporal, ew_filter_outlier;
extern const ew_op_type ew_filter_pyramid, ew_filter_bilateral, ew_filter_separable, ew_filter_atrous, ew_filter_dof;

#ifdef EW_EXTRA_OP_TYPES
#define EW_REGISTRY_LINKAGE
#else
#define EW_EXTRA_OP_TYPES
#define EW_REGISTRY_LINKAGE __attribute__((weak))
#endif

EW_REGISTRY_LINKAGE const ew_op_type *const ew_op_types[] = {
    &ew_denoise_auto,
    &ew_denoise_bgrid,
    &ew_denoise_nbg,
    &ew_denoise_kpcn,
    &ew_filter_pyramid,
    &ew_filter_bilateral,
    &ew_filter_separable,
    &ew_filter_atrous,
    &ew_filter_dof,
    &ew_filter_temporal,
    &ew_filter_outlier,
    EW_EXTRA_OP_TYPES
    NULL,
};
