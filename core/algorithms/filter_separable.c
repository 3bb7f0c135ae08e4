/* filter "separable": the separable bilateral approximation; shared code in bilateral_op.c. */
#include "algorithms/bilateral_op.h"

static const ew_image_desc images[] = {EW_BF_OP_IMAGES};

static const ew_param_desc params[] = {
    EW_BF_OP_PARAMS,
};

static ew_result commit(ew_op *op) { return ew_bf_op_commit(op, EW_BF_SEPARABLE); }

const ew_op_type ew_filter_separable = {
    .kind = "filter",
    .name = "separable",
    .summary = "separable bilateral approximation (a horizontal then a vertical 1-D pass, what games use); cost grows with the radius",
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
EW_REGISTER_OP(ew_filter_separable, 70);
