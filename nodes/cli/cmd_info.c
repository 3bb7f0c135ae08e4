#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cycles_passes.h"

int cmd_info(int argc, char **argv) {
    if (argc != 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        fputs("usage: edgewise info FILE\n\nPrint the size, layers, passes (the colour the file shows, 'Combined', and\n"
              "what a denoiser would read when that differs: 'Noisy Image' of a denoised\n"
              "file) and sample count of an image file.\n",
              argc == 2 ? stdout : stderr);
        return argc == 2 ? 0 : EW_EXIT_USAGE;
    }
    char err[512];
    ewio_file *f = NULL;
    if (ewio_read(argv[1], &f, err, sizeof err) != 0) return cli_fail("%s", err);
    printf("%s: %dx%d, %d channels\n", argv[1], ewio_width(f), ewio_height(f), ewio_num_channels(f));
    for (int i = 0; i < ewio_num_layers(f); i++) {
        const char *layer = ewio_layer_name(f, i);
        ew_layer_passes lp, noisy;
        printf("layer '%s'", layer);
        if (ew_find_image_passes(f, layer, &lp, err, sizeof err) == 0 &&
            ew_find_layer_passes(f, layer, &noisy, err, sizeof err) == 0) {
            printf(": colour '%s'", lp.color);
            /* a denoised file: what compare/filter show is not what denoise reads */
            if (strcmp(noisy.color, lp.color) != 0) printf(" (denoise reads '%s')", noisy.color);
            printf(", albedo %s%s%s, normal %s%s%s, depth %s%s%s\n",
                   lp.albedo ? "'" : "", lp.albedo ? lp.albedo : "missing", lp.albedo ? "'" : "",
                   lp.normal ? "'" : "", lp.normal ? lp.normal : "missing", lp.normal ? "'" : "",
                   lp.depth ? "'" : "", lp.depth ? lp.depth : "missing", lp.depth ? "'" : "");
        } else
            printf(": no colour pass\n");
        char key[600];
        snprintf(key, sizeof key, "cycles.%s.samples", layer);
        const char *spp = ewio_get_attribute(f, key);
        if (spp && *spp) printf("  samples: %s\n", spp);
    }
    printf("channels:");
    for (int i = 0; i < ewio_num_channels(f); i++) printf("%s %s", i ? "," : "", ewio_channel_name(f, i));
    printf("\n");
    ewio_free(f);
    return 0;
}
