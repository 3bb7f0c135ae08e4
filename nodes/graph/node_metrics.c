/*
 * node_metrics.c — PSNR and SSIM of an image against a reference, through
 * the library's metrics (tone-mapped as a display shows them), written to
 * the graph's report for every frame.
 */
#include "graph.h"

static const ew_port_desc metrics_in[] = {
    {"image", EW_PASS_ANY, 1, 1, "image to assess"},
    {"reference", EW_PASS_ANY, 1, 1, "ground truth, e.g. a high-sample render"},
};

static ew_result metrics_execute(ew_gnode *n, ew_run *r) {
    const ew_image *im = ew_node_in(n, "image"), *ref = ew_node_in(n, "reference");
    double psnr = 0.0, ssim = 0.0;
    ew_result res = ew_image_psnr(n->g->dev, im, ref, &psnr);
    if (res == EW_OK) res = ew_image_ssim(n->g->dev, im, ref, &ssim);
    if (res != EW_OK) return ew_node_fail(n, res, "%s", ew_device_last_error(n->g->dev));
    ew_run_report_number(r, n, "psnr", psnr);
    ew_run_report_number(r, n, "ssim", ssim);
    return EW_OK;
}

const ew_node_type ew_node_metrics = {
    .name = "metrics", .version = 1, .category = "analysis",
    .summary = "PSNR (dB) and SSIM against a reference, per frame, into the run's report",
    .inputs = metrics_in, .num_inputs = 2, .inplace_input = -1, .is_sink = 1, .execute = metrics_execute,
};
