/*
 * insn_window: a QEMU TCG plugin that counts guest instructions executed
 * between two code addresses ("windows").
 *
 *   qemu-system-arm ... -plugin ./insn_window.so,begin=0x82d0,end=0x82fc,out=win.txt
 *
 * A window starts when the instruction at `begin` is about to execute and ends
 * when the instruction at `end` is about to execute; its length (instructions
 * executed from `begin` inclusive to `end` exclusive) is written to `out`, one
 * decimal number per line, in execution order. The last line is
 * "total <n>": all instructions executed in the run.
 *
 * Optional `prof=FILE`: a flat profile of the instructions executed inside
 * windows, one line per translated block, "<start address hex> <insns> <times
 * executed in a window>" (bench_insn.py --profile maps them to symbols).
 * With `pwin=K` as well, of window K alone (from 0, in execution order): one
 * tick's instructions by function (wcet.py profile).
 *
 * Counting: every translated block adds its instruction count to a counter
 * when it starts (an inline op, cheap); the marker instructions get a callback
 * that corrects for their position in the block. Exact as long as blocks run
 * to their end, which holds here: no interrupts are enabled in the windows,
 * and an instruction that raises an exception (semihosting BKPT) ends its
 * block at translation time.
 *
 * Plugin API version 1, as in QEMU 7.2 (Debian bookworm's qemu-system-arm);
 * QEMU installs no plugin header, so the few declarations needed are written
 * out below from the API documentation.
 */
#include <inttypes.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

typedef uint64_t qemu_plugin_id_t;
typedef struct {
    const char *target_name;
    struct { int min; int cur; } version;
    bool system_emulation;
    /* further fields unused */
} qemu_info_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*udata_cb_t)(qemu_plugin_id_t id, void *userdata);

void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, tb_trans_cb_t cb);
void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb, enum qemu_plugin_op op,
                                              void *ptr, uint64_t imm);
void qemu_plugin_register_vcpu_tb_exec_cb(struct qemu_plugin_tb *tb, vcpu_udata_cb_t cb,
                                          enum qemu_plugin_cb_flags flags, void *userdata);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, vcpu_udata_cb_t cb,
                                            enum qemu_plugin_cb_flags flags, void *userdata);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *tb);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, udata_cb_t cb, void *userdata);
void qemu_plugin_outs(const char *string);

EXPORT int qemu_plugin_version = 1;

static uint64_t begin_addr, end_addr;
static uint64_t executed;  /* instructions of all blocks started so far */
static uint64_t win_start;
static bool win_open;
static FILE *out;
static FILE *prof;

struct block {
    uint64_t vaddr, n, in_window;
    struct block *next;
};
static struct block *blocks;
/* the window profiled (-1: all) and the index of the one open */
static long long pwin = -1, nwin = -1;

static void on_block(unsigned int vcpu, void *ud)
{
    (void)vcpu;
    if (win_open && (pwin < 0 || nwin == pwin)) {
        ((struct block *)ud)->in_window++;
    }
}

/* userdata = instructions of the block from the marker to its end (n - idx) */
static void on_begin(unsigned int vcpu, void *ud)
{
    (void)vcpu;
    win_start = executed - (uint64_t)(uintptr_t)ud;
    win_open = true;
    nwin++;
}

static void on_end(unsigned int vcpu, void *ud)
{
    (void)vcpu;
    if (win_open) {
        fprintf(out, "%" PRIu64 "\n", executed - (uint64_t)(uintptr_t)ud - win_start);
        win_open = false;
    }
}

static void on_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &executed, n);
    if (prof) {
        struct block *b = calloc(1, sizeof *b);
        if (b) {
            b->vaddr = qemu_plugin_tb_vaddr(tb);
            b->n = n;
            b->next = blocks;
            blocks = b;
            qemu_plugin_register_vcpu_tb_exec_cb(tb, on_block, QEMU_PLUGIN_CB_NO_REGS, b);
        }
    }
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t va = qemu_plugin_insn_vaddr(insn);
        if (va == begin_addr || va == end_addr) {
            qemu_plugin_register_vcpu_insn_exec_cb(insn, va == begin_addr ? on_begin : on_end,
                                                   QEMU_PLUGIN_CB_NO_REGS,
                                                   (void *)(uintptr_t)(n - i));
        }
    }
}

static void on_exit_cb(qemu_plugin_id_t id, void *ud)
{
    (void)id;
    (void)ud;
    if (out) {
        fprintf(out, "total %" PRIu64 "\n", executed);
        fflush(out);
    }
    if (prof) {
        for (struct block *b = blocks; b; b = b->next) {
            if (b->in_window) {
                fprintf(prof, "%" PRIx64 " %" PRIu64 " %" PRIu64 "\n", b->vaddr, b->n, b->in_window);
            }
        }
        fflush(prof);
    }
}

EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv)
{
    (void)info;
    const char *path = NULL, *prof_path = NULL;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "begin=", 6) == 0) {
            begin_addr = strtoull(argv[i] + 6, NULL, 0);
        } else if (strncmp(argv[i], "end=", 4) == 0) {
            end_addr = strtoull(argv[i] + 4, NULL, 0);
        } else if (strncmp(argv[i], "out=", 4) == 0) {
            path = argv[i] + 4;
        } else if (strncmp(argv[i], "pwin=", 5) == 0) {
            pwin = strtoll(argv[i] + 5, NULL, 0);
        } else if (strncmp(argv[i], "prof=", 5) == 0) {
            prof_path = argv[i] + 5;
        } else {
            qemu_plugin_outs("insn_window: unknown argument\n");
            return -1;
        }
    }
    if (!path || !begin_addr || !end_addr || begin_addr == end_addr) {
        qemu_plugin_outs("insn_window: need begin=ADDR,end=ADDR,out=FILE\n");
        return -1;
    }
    out = fopen(path, "w");
    if (!out) {
        qemu_plugin_outs("insn_window: cannot open out file\n");
        return -1;
    }
    if (prof_path && !(prof = fopen(prof_path, "w"))) {
        qemu_plugin_outs("insn_window: cannot open prof file\n");
        return -1;
    }
    static char buf[1 << 20];
    setvbuf(out, buf, _IOFBF, sizeof buf);
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_trans);
    qemu_plugin_register_atexit_cb(id, on_exit_cb, NULL);
    return 0;
}
