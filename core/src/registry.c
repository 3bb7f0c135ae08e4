/* Every denoiser and filter the library offers, in the order tools list them. */
#include "src/op.h"

extern const ew_op_type ew_denoise_bgrid, ew_denoise_auto;
extern const ew_op_type ew_denoise_nbg; /* issue 3 */
extern const ew_op_type ew_filter_temporal, ew_filter_outlier;
extern const ew_op_type ew_filter_pyramid, ew_filter_bilateral, ew_filter_separable, ew_filter_atrous, ew_filter_dof;

const ew_op_type *const ew_op_types[] = {
    &ew_denoise_auto,
    &ew_denoise_bgrid,
    &ew_denoise_nbg,
    &ew_filter_pyramid,
    &ew_filter_bilateral,
    &ew_filter_separable,
    &ew_filter_atrous,
    &ew_filter_dof,
    &ew_filter_temporal,
    &ew_filter_outlier,
    NULL,
};
