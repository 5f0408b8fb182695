/*
 * Replay driver: runs the fuzz target on saved inputs without libFuzzer, so the regression
 * inputs can be checked by gcc + ASan/UBSan builds on machines that never run the fuzzer.
 *
 *     fuzz_replay [--fix-crc | --sign] PATH...     (a PATH may be a file or a folder of inputs)
 *
 * Prints one line per input (with the link's frame and error counters after it) and a summary;
 * exits 0 when every input ran to its end (a crash or sanitizer report ends the process with
 * the sanitizer's own non-zero status).
 */
#define _POSIX_C_SOURCE 200809L /* opendir, stat under -std=c11 */

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fuzz_link.h"
#include "link.h"

#define REPLAY_MAX 65536u

static unsigned s_runs;

static int replay_file(const char *path)
{
    static uint8_t buf[REPLAY_MAX];
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        fprintf(stderr, "replay: cannot open %s\n", path);
        return 1;
    }
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    int rc = LLVMFuzzerTestOneInput(buf, n);
    const link_state_t *ls = link_state(); /* what the firmware made of it, for the tests */
    printf("replay: %s (%zu bytes)%s rx_frames=%u rx_errors=%u rx_unknown=%u rx_unsigned=%u rx_bad_signature=%u"
           " rx_replay=%u\n", path, n, rc != 0 ? " rejected (too long)" : "", (unsigned)ls->rx_frames,
           (unsigned)ls->rx_errors, (unsigned)ls->rx_unknown, (unsigned)ls->rx_unsigned,
           (unsigned)ls->rx_bad_signature, (unsigned)ls->rx_replay);
    s_runs++;
    return 0;
}

static int cmp_names(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static int replay_path(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        fprintf(stderr, "replay: no such input %s\n", path);
        return 1;
    }
    if (!S_ISDIR(st.st_mode)) {
        return replay_file(path);
    }
    DIR *d = opendir(path);
    if (d == NULL) {
        return 1;
    }
    char **names = NULL;
    size_t count = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.') {
            continue;
        }
        names = realloc(names, (count + 1u) * sizeof *names);
        size_t len = strlen(path) + strlen(e->d_name) + 2u;
        names[count] = malloc(len);
        snprintf(names[count], len, "%s/%s", path, e->d_name);
        count++;
    }
    closedir(d);
    qsort(names, count, sizeof *names, cmp_names); /* a fixed order, for comparable logs */
    int failed = 0;
    for (size_t i = 0; i < count; i++) {
        struct stat fs;
        if (stat(names[i], &fs) == 0 && S_ISREG(fs.st_mode)) {
            failed |= replay_file(names[i]);
        }
        free(names[i]);
    }
    free(names);
    return failed;
}

int main(int argc, char **argv)
{
    int failed = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--fix-crc") == 0) {
            fuzz_fix_crc = 1;
        } else if (strcmp(argv[i], "--sign") == 0) {
            fuzz_fix_crc = 2;
        } else {
            failed |= replay_path(argv[i]);
        }
    }
    static const char *const MODE_NAMES[] = {"raw", "fix-crc", "sign"};
    printf("replay: %u inputs, mode %s, %s\n", s_runs, MODE_NAMES[fuzz_fix_crc], failed ? "errors" : "ok");
    return failed ? 2 : 0;
}
