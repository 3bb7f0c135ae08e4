/* Every denoiser and filter the library offers, in the order tools list them. */
#include "src/op.h"

extern const ew_op_type ew_denoise_bgrid;

const ew_op_type *const ew_op_types[] = {
    &ew_denoise_bgrid,
    NULL,
};
