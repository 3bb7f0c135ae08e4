/* Corpus replay: runs a fuzz target over every file of the given
 * directories, plus every single-byte flip and every truncation of each
 * file, so the fuzz targets run as ordinary tests without libFuzzer. */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static unsigned char *slurp(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    unsigned char *buf = NULL;
    size_t cap = 0, n = 0;
    for (;;) {
        if (n == cap) {
            cap = cap ? cap * 2 : 4096;
            unsigned char *nb = realloc(buf, cap);
            if (!nb) { free(buf); fclose(f); return NULL; }
            buf = nb;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) break;
    }
    fclose(f);
    *size = n;
    return buf;
}

int main(int argc, char **argv) {
    int files = 0, runs = 0;
    for (int a = 1; a < argc; a++) {
        DIR *d = opendir(argv[a]);
        if (!d) { fprintf(stderr, "replay: cannot open corpus '%s'\n", argv[a]); printf("0 passed, 1 failed\n"); return 1; }
        struct dirent *e;
        while ((e = readdir(d))) {
            if (e->d_name[0] == '.') continue;
            char path[4096];
            snprintf(path, sizeof path, "%s/%s", argv[a], e->d_name);
            size_t n;
            unsigned char *buf = slurp(path, &n);
            if (!buf) continue;
            files++;
            LLVMFuzzerTestOneInput(buf, n);
            runs++;
            unsigned char *m = malloc(n ? n : 1);
            for (size_t i = 0; i < n; i++) {
                memcpy(m, buf, n);
                m[i] ^= (unsigned char)(0x01u << (i % 8));
                LLVMFuzzerTestOneInput(m, n);
                LLVMFuzzerTestOneInput(buf, i);
                runs += 2;
            }
            free(m);
            free(buf);
        }
        closedir(d);
    }
    if (files == 0) { fprintf(stderr, "replay: empty corpus\n"); printf("0 passed, 1 failed\n"); return 1; }
    printf("%d passed, 0 failed\n", runs);
    return 0;
}
