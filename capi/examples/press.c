/* A probe pressing into a block of soft tissue through lancet's C ABI.
 *
 * Build (from the repository root, after `cargo build -p lancet-capi`):
 *   cc -std=c99 -Wall -Icapi/include capi/examples/press.c -Ltarget/debug -llancet_c \
 *      -Wl,-rpath,target/debug -o press
 * Run: ./press [positions.txt]
 * It prints the force on the probe every 50 steps and, given a file name, writes the final
 * node positions to it (one "x y z" line per node, %.17g: exact doubles). */
#include <stdio.h>
#include <stdlib.h>
#include "lancet.h"

static int check(LancetStatus s, const char *what) {
    if (s != LANCET_STATUS_OK) {
        fprintf(stderr, "%s failed (status %d): %s\n", what, (int)s, lancet_last_error());
        return 1;
    }
    return 0;
}

int main(int argc, char **argv) {
    /* A 2 cm cube of 4 x 4 x 4 cells, E = 10 kPa, its base held, under gravity. */
    const double size[3] = {0.02, 0.02, 0.02};
    const uint32_t cells[3] = {4, 4, 4};
    LancetMaterial material = {10e3, 0.3, 1000.0, 20.0, {0.0, 0.0, -9.81}};
    LancetSettings settings = {LANCET_ENGINE_REFERENCE, LANCET_INTEGRATOR_VERLET, 0.0, 0.5, 1,
                               {-1.0, -1.0, -1e-9}, {1.0, 1.0, 1e-9}};
    LancetWorld *world = NULL;
    if (check(lancet_world_new_box(size, cells, &material, &settings, &world), "new box"))
        return 1;

    /* A 3 mm sphere just above the middle of the top face. */
    LancetToolDesc sphere = {LANCET_TOOL_KIND_SPHERE, 0.003, 0.0, 0.0, 0.0, {0.0, 0.0, 0.0}, 0.0};
    LancetPose pose = {{0.01, 0.01, 0.0235}, {1.0, 0.0, 0.0, 0.0}};
    uint32_t probe = 0;
    if (check(lancet_world_add_tool(world, "probe", &sphere, &pose, &probe), "add tool"))
        return 1;

    /* The per-step order: pose the tool for the end of the step, step, read the force. */
    const int steps = 300;
    for (int k = 1; k <= steps; k++) {
        pose.position[2] = 0.0235 - 2e-3 * k / steps; /* down 2 mm over the run */
        if (check(lancet_world_set_tool_pose(world, probe, &pose), "set pose")) return 1;
        LancetStepInfo info;
        if (check(lancet_world_step(world, &info), "step")) return 1;
        if (k % 50 == 0) {
            double f[3];
            if (check(lancet_world_tool_force(world, probe, f), "tool force")) return 1;
            printf("step %llu  t = %.4f s  contacts %u  force (%.4f, %.4f, %.4f) N\n",
                   (unsigned long long)info.step, info.time, info.contacts, f[0], f[1], f[2]);
        }
    }

    size_t n = lancet_world_node_count(world);
    double *x = malloc(3 * n * sizeof(double));
    if (!x || check(lancet_world_positions(world, x, 3 * n), "positions")) return 1;
    if (argc > 1) {
        FILE *out = fopen(argv[1], "w");
        if (!out) { perror(argv[1]); return 1; }
        for (size_t i = 0; i < n; i++)
            fprintf(out, "%.17g %.17g %.17g\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        fclose(out);
    }
    printf("%zu nodes, lancet %s\n", n, lancet_version());

    /* A bad call returns a status and a message, never aborts. */
    if (lancet_world_set_tool_pose(world, 7, &pose) != LANCET_STATUS_INVALID_ARGUMENT) return 1;
    printf("expected error: %s\n", lancet_last_error());

    free(x);
    lancet_world_free(world);
    return 0;
}
