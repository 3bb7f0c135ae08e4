/* filter "bilateral": the exact joint bilateral filter (ground truth); shared code in bilateral_op.c. */
#include "algorithms/bilateral_op.h"

static const ew_image_desc images[] = {EW_BF_OP_IMAGES};

static const ew_param_desc params[] = {
    EW_BF_OP_PARAMS,
};

static ew_result commit(ew_op *op) { return ew_bf_op_commit(op, EW_BF_BRUTE); }

const ew_op_type ew_filter_bilateral = {
    .kind = "filter",
    .name = "bilateral",
    .summary = "joint bilateral filter, exact (Eq. 1 of Xu et al. 2024): the ground truth; cost grows with radius^2",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = ew_bf_op_execute,
    .release = ew_bf_op_release,
    .pixel_params = EW_BF_OP_PIXEL_PARAMS,
    .choices = (const ew_param_choices[]){EW_BF_MODEL_CHOICES, {NULL, NULL}},
    .inplace_inputs = EW_BF_OP_INPLACE,
    .denoises = 1,
    .filters_alpha = 1,
    .alpha_guides = ew_bf_op_alpha_guides,
};
EW_REGISTER_OP(ew_filter_bilateral, 60);
