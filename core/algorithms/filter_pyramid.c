/* filter "pyramid": the pyramid edge-preserving filter; shared code in bilateral_op.c. */
#include "algorithms/bilateral_op.h"

static const ew_image_desc images[] = {EW_BF_OP_IMAGES};

static const ew_param_desc params[] = {
    EW_BF_OP_PARAMS,
    EW_PYR_WEIGHTS_PARAM,
};

static ew_result commit(ew_op *op) { return ew_bf_op_commit(op, EW_BF_PYRAMID); }

const ew_op_type ew_filter_pyramid = {
    .kind = "filter",
    .name = "pyramid",
    .summary = "pyramid edge-preserving filter (Xu et al. 2024): 2x2 range-weighted downsampling, dual 3x3 upsampling; cost independent of the radius",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = ew_bf_op_execute,
    .release = ew_bf_op_release,
    .set_data = ew_pyr_op_set_data,
    .release_data = ew_pyr_op_release_data,
    .pixel_params = EW_BF_OP_PIXEL_PARAMS,
    .choices = (const ew_param_choices[]){EW_BF_MODEL_CHOICES, EW_PYR_WEIGHTS_CHOICES, {NULL, NULL}},
    .inplace_inputs = EW_BF_OP_INPLACE,
    .filters_alpha = 1,
    .alpha_guides = ew_bf_op_alpha_guides,
    /* radius 0: no filtering at all, whatever the model */
    .noop_at_zero = (const char *const[]){"radius", NULL},
    .data_params = (const char *const[]){"weights", "weights", NULL},
    .flags = EW_METHOD_HOST,
    .denoises = 1,
};
EW_REGISTER_OP(ew_filter_pyramid, 50);
