/*
 * edgewise dof — depth of field on a sharp render from its depth pass and
 * the values of a Blender camera: the library's "dof" filter (thin-lens CoC,
 * then the pyramid filter with the paper's DoF functions), its options
 * generated from the filter's descriptor (cli_op.c).
 */
#include "cli.h"

static const cli_op_command dof_command = {
    .name = "dof",
    .kind = "filter",
    .method = "dof",
    .pass_option = 0,
    .intro = "Add depth of field to a sharp (pinhole) render. IN needs a colour pass and a\n"
             "depth pass: a Cycles multilayer EXR with Depth (planar camera depth in metres;\n"
             "Blender: View Layer > Passes > Data > Z). The camera values are the ones of a\n"
             "Blender camera. A blurred background stays behind a sharp foreground, and a\n"
             "blurred foreground spreads over a sharp background. An EXR output keeps every\n"
             "other layer, pass and the metadata of IN; PNG/TIFF/JPEG get the colour only.\n"
             "An RGBA colour is premultiplied: alpha is blurred with it.\n",
    .outro = NULL,
};

int cmd_dof(int argc, char **argv) { return cli_op_run(&dof_command, argc, argv); }
