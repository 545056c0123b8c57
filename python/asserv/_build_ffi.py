"""cffi build script of asserv._core: the board's C sources compiled into the Python package,
so that Python drives exactly the code the board runs (run by setup.py at install time)."""

from pathlib import Path

from cffi import FFI

ROOT = Path(__file__).resolve().parents[2]
CORE = ROOT / "firmware" / "core"

SOURCES = [CORE / "protocol.c", CORE / "protocol_table.c"]

CDEF = """
#define PROTO_MAX_PARAMS ...
#define PROTO_MAX_REPLY ...

struct proto_msg {
    uint8_t designation;
    uint8_t n_args;
    int32_t arg[...];
    ...;
};

struct proto_debug {
    uint16_t tick;
    int16_t heading_cdeg;
    int16_t speed_mm_s;
    int16_t turn_rate_cdeg_s;
    int16_t dist_err_um;
    int16_t angle_err_um;
    int16_t duty_left_q15;
    int16_t duty_right_q15;
    int16_t current_left_ma;
    int16_t current_right_ma;
    uint8_t order_state;
    uint8_t end_reason;
};

struct proto_snapshot {
    int16_t x_mm;
    int16_t y_mm;
    int8_t angle_2deg;
    uint8_t radius_mm;
    uint8_t status;
    uint8_t sensors;
    struct proto_debug debug;
};

struct proto { ...; };

uint8_t proto_crc8(uint8_t crc, const uint8_t *data, uint8_t n);
void proto_init(struct proto *p);
void proto_on_write_start(struct proto *p);
void proto_on_byte(struct proto *p, uint8_t byte);
void proto_on_read_start(struct proto *p);
uint8_t proto_read_byte(struct proto *p);
void proto_on_stop(struct proto *p);
void proto_on_abort(struct proto *p);
int proto_poll(struct proto *p, struct proto_msg *out);
void proto_publish(struct proto *p, const struct proto_snapshot *s);
uint8_t proto_status(const struct proto *p);
"""

ffibuilder = FFI()
ffibuilder.cdef(CDEF)
ffibuilder.set_source(
    "asserv._core",
    '#include "protocol.h"\n',
    sources=[str(s.relative_to(ROOT)) for s in SOURCES],
    include_dirs=[str(CORE.relative_to(ROOT))],
    extra_compile_args=["-std=c99", "-Wall", "-Wextra"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
