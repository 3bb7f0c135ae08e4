/* Fuzz target for the weights parser: any bytes either parse into tensors
 * that pass the checks or are rejected with a message — never a crash.
 * Built with clang -fsanitize=fuzzer for fuzzing; in the ordinary build
 * replay_main.c runs it over the corpus as a test. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "src/weights.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    ew_weights w;
    char err[256];
    if (ew_weights_parse(data, size, &w, err, sizeof err) == 0) {
        /* a parsed file must serialise back to the same bytes */
        void *again;
        size_t n;
        if (ew_weights_serialize(&w, &again, &n) == 0) {
            if (n != size || memcmp(again, data, n) != 0) __builtin_trap();
            free(again);
        }
        ew_weights_free(&w);
    } else if (err[0] == '\0') {
        __builtin_trap(); /* a rejection always says why */
    }
    return 0;
}
