/*
 * edgewise filter — one of the library's filters on one pass of an image.
 * Options come from the filter's descriptor (cli_op.c). The output keeps
 * every other layer, pass and the metadata (EXR).
 */
#include "cli.h"

static const cli_op_command filter_command = {
    .name = "filter",
    .kind = "filter",
    .method = NULL,
    .pass_option = 1,
    .intro = "Filter one pass of IN (by default the colour the file shows: Combined of the\n"
             "first view layer of a Cycles multilayer EXR, or a plain EXR/PNG/TIFF/JPEG image)\n"
             "with one of the library's filters and write it to OUT. An EXR output keeps\n"
             "every other layer, pass and the metadata of IN; PNG/TIFF/JPEG get the\n"
             "filtered pass only. Each filter's images are read from passes (--NAME-pass; normal,\n"
             "depth, albedo and vector default to the Cycles passes that hold them), its\n"
             "parameters are --NAME VALUE with the library's ranges and defaults.\n",
    .outro = "Non-finite samples (NaN, Inf) in the filtered pass are treated as missing and\n"
             "rebuilt from their neighbourhood; their count is reported. An RGBA pass is\n"
             "premultiplied colour: pyramid, bilateral and separable filter alpha with the\n"
             "colour's weights, so colour stays within alpha; atrous filters alpha with\n"
             "weights of its own; outlier and temporal leave alpha as it is.\n",
};

int cmd_filter(int argc, char **argv) { return cli_op_run(&filter_command, argc, argv); }
