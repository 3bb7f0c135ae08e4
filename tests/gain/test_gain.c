/* The guide's example method against its obvious reference, through the
 * public API of the test library that has it (tests/gain). This is the
 * method's own test, file 4 of docs/adding-a-method.md. */
#include "ew_test.h"

#include "edgewise/edgewise.h"

TEST(gain_scales_every_channel_or_keeps_alpha) {
    enum { W = 13, H = 7, C = 4 };
    static float in[W * H * C], out[W * H * C];
    for (int i = 0; i < W * H * C; i++) in[i] = (float)((i * 37) % 101) / 17.0f - 1.0f;
    ew_device *dev = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    for (int keep = 0; keep < 2; keep++) {
        ew_op *op = NULL;
        CHECK_EQ_INT(ew_op_create(dev, "gain", &op), EW_OK);
        ew_image vi = ew_image_packed(in, W, H, C), vo = ew_image_packed(out, W, H, C);
        CHECK_EQ_INT(ew_op_set_image(op, "color", &vi), EW_OK);
        CHECK_EQ_INT(ew_op_set_image(op, "output", &vo), EW_OK);
        CHECK_EQ_INT(ew_op_set_float(op, "gain", 2.5f), EW_OK);
        CHECK_EQ_INT(ew_op_set_int(op, "alpha", keep), EW_OK);
        CHECK_EQ_INT(ew_op_commit(op), EW_OK);
        CHECK_EQ_INT(ew_op_execute(op), EW_OK);
        for (int i = 0; i < W * H * C; i++) {
            float want = (keep && i % C == 3) ? in[i] : in[i] * 2.5f;
            if (out[i] != want) {
                FAIL_AT("sample %d: %g, want %g", i, (double)out[i], (double)want);
                break;
            }
        }
        ew_op_destroy(op);
    }
    ew_device_destroy(dev);
}
