/* Peak float32 throughput of this CPU, measured: independent FMA chains on the widest vectors
 * the compiler targets (-march=native), and the same for sqrt and divide, which the spring
 * force needs once each per spring. Usage: peakflops THREADS. Prints one JSON line.
 * Build: cc -O3 -march=native -fno-math-errno -pthread peakflops.c -o peakflops -lm */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define W 16 /* lanes per vector (GCC vector extension: the compiler splits if narrower) */
typedef float vf __attribute__((vector_size(W * 4)));
#define CHAINS 12

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static long iters = 20000000;
static volatile float sink;

static void *fma_loop(void *arg) {
    (void)arg;
    vf acc[CHAINS], a, b;
    for (int i = 0; i < W; i++) { a[i] = 0.999999f; b[i] = 1e-7f; }
    for (int c = 0; c < CHAINS; c++) for (int i = 0; i < W; i++) acc[c][i] = (float)c;
    for (long k = 0; k < iters; k++)
        for (int c = 0; c < CHAINS; c++) acc[c] = acc[c] * a + b;
    float s = 0;
    for (int c = 0; c < CHAINS; c++) s += acc[c][0];
    sink = s;
    return NULL;
}

static void *sqrt_div_loop(void *arg) {
    (void)arg;
    vf x[CHAINS], one;
    for (int i = 0; i < W; i++) one[i] = 1.0f;
    for (int c = 0; c < CHAINS; c++) for (int i = 0; i < W; i++) x[c][i] = 1.5f + c + i;
    for (long k = 0; k < iters / 16; k++)
        for (int c = 0; c < CHAINS; c++) {
            vf r;
            for (int i = 0; i < W; i++) r[i] = __builtin_sqrtf(x[c][i]);
            x[c] = one / r + one; /* one sqrt + one divide per lane */
        }
    float s = 0;
    for (int c = 0; c < CHAINS; c++) s += x[c][0];
    sink = s;
    return NULL;
}

static double run(int threads, void *(*fn)(void *)) {
    pthread_t t[64];
    double t0 = now();
    for (int i = 0; i < threads; i++) pthread_create(&t[i], NULL, fn, NULL);
    for (int i = 0; i < threads; i++) pthread_join(t[i], NULL);
    return now() - t0;
}

int main(int argc, char **argv) {
    int threads = argc > 1 ? atoi(argv[1]) : 1;
    double best_fma = 1e30, best_sd = 1e30;
    for (int r = 0; r < 3; r++) {
        double t = run(threads, fma_loop);
        if (t < best_fma) best_fma = t;
        t = run(threads, sqrt_div_loop);
        if (t < best_sd) best_sd = t;
    }
    double fma_flops = 2.0 * W * CHAINS * (double)iters * threads;
    double sd_pairs = (double)W * CHAINS * (double)(iters / 16) * threads;
    printf("{\"threads\": %d, \"fma_gflops\": %.2f, \"sqrt_div_gpairs\": %.3f}\n", threads,
           fma_flops / best_fma / 1e9, sd_pairs / best_sd / 1e9);
    return 0;
}
