/* Every denoiser and filter the library offers, in the order tools list them. */
#include "src/op.h"

extern const ew_op_type ew_denoise_bgrid, ew_denoise_auto;
extern const ew_op_type ew_filter_temporal;

const ew_op_type *const ew_op_types[] = {
    &ew_denoise_auto,
    &ew_denoise_bgrid,
    &ew_filter_temporal,
    NULL,
};
