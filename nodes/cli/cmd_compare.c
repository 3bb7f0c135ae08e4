#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

int cmd_compare(int argc, char **argv) {
    if (argc == 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
        fputs("usage: edgewise compare TEST REF\n\nPSNR (dB) and SSIM of TEST against REF on tone-mapped colour\n"
              "(clip to [0,1], gamma 1/2.2). Uses each file's first layer with a colour\n"
              "pass (Combined for Cycles renders).\n",
              stdout);
        return 0;
    }
    if (argc != 3) {
        fputs("usage: edgewise compare TEST REF\n", stderr);
        return EW_EXIT_USAGE;
    }
    char err[512];
    ewio_file *a = NULL, *b = NULL;
    float *pa = NULL, *pb = NULL;
    int rc = EW_EXIT_FAIL;
    if (ewio_read(argv[1], &a, err, sizeof err) != 0) { cli_fail("%s", err); goto done; }
    if (ewio_read(argv[2], &b, err, sizeof err) != 0) { cli_fail("%s", err); goto done; }
    if (!(pa = cli_read_color(a, NULL, err, sizeof err))) { cli_fail("'%s': %s", argv[1], err); goto done; }
    if (!(pb = cli_read_color(b, NULL, err, sizeof err))) { cli_fail("'%s': %s", argv[2], err); goto done; }
    ew_device *dev = cli_device(1, 0);
    if (!dev) goto done;
    ew_image va = ew_image_packed(pa, ewio_width(a), ewio_height(a), 3);
    ew_image vb = ew_image_packed(pb, ewio_width(b), ewio_height(b), 3);
    double psnr, ssim;
    if (ew_image_psnr(dev, &va, &vb, &psnr) != EW_OK || ew_image_ssim(dev, &va, &vb, &ssim) != EW_OK) {
        cli_fail("%s", ew_device_last_error(dev));
    } else {
        printf("PSNR %.2f dB  SSIM %.4f\n", psnr, ssim);
        rc = 0;
    }
    ew_device_destroy(dev);
done:
    free(pa);
    free(pb);
    ewio_free(a);
    ewio_free(b);
    return rc;
}
