"""cffi build script of asserv_sim._core: the board's C sources (control core, protocol layer, host
port) and the physics simulator compiled for Python, so that Python drives exactly the code the
board runs (run by setup.py when asserv-sim is built: ``pip install "asserv[sim]"``).

The sources are under csrc/: in the repository, links to firmware/ and sim/; in the sdist, the
files themselves. Paths are relative to this directory, where setuptools runs."""

from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
ROOT = HERE / "csrc"
CORE = ROOT / "firmware" / "core"
SIM = ROOT / "sim"
PORTS = ROOT / "firmware" / "ports"

SOURCES = [
    *sorted(CORE.glob("*.c")),
    *(SIM / n for n in ("config.c", "field.c", "rng.c", "robot.c")),
    PORTS / "common" / "port.c",
    PORTS / "common" / "nvm_bytes.c",
    PORTS / "common" / "calib_store.c",
    PORTS / "common" / "calib_log.c",
    PORTS / "host" / "host.c",
]
INCLUDES = [
    CORE,
    ROOT / "firmware" / "arch" / "generic",
    ROOT / "firmware" / "hal",
    PORTS / "common",
    PORTS / "host",
    SIM,
]

# Only what Python touches is declared; "...;" lets the C compiler fill in the rest of a struct,
# and a mismatch with the headers is a build error (cffi API mode).
CDEF = """
#define PROTO_MAX_PARAMS ...
#define PROTO_MAX_REPLY ...
#define SIM_MAX_SHOCK ...
#define SIM_MAX_LINE_SENSORS ...
#define SIM_MAX_OBSTACLES ...
#define UNCERTAINTY_STAGES ...
#define SIM_MAX_LINES ...
#define SIM_MAX_OPPONENTS ...
#define SIM_MAX_PATH ...
#define SIM_SHAPE_CIRCLE ...
#define SIM_SHAPE_BOX ...
#define SIM_OBSTACLE_BASKET ...
#define SIM_OBSTACLE_OTHER ...

/* ---- protocol layer (firmware/core/protocol.h) ---- */
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

struct proto_motion {
    uint8_t running_seq;
    uint8_t pending;
    uint8_t flags;
    uint8_t last_seq;
    uint8_t last_end;
    uint16_t braking_mm;
    uint16_t braking_ms;
    uint8_t scale_percent;
    uint8_t appends_done;
};

struct proto_fix {
    uint16_t fused;
    uint16_t outliers;
    uint16_t too_old;
    uint8_t last;
    uint8_t last_d2;
};

struct proto_reset {
    uint8_t tracked;
    uint8_t cause;
    uint8_t count;
    uint8_t pose_lost;
    uint8_t widened_mm;
};

struct proto_snapshot {
    int16_t x_mm;
    int16_t y_mm;
    int8_t angle_2deg;
    uint8_t radius_mm;
    uint8_t status;
    uint8_t sensors;
    uint8_t calibrated;
    struct proto_debug debug;
    struct proto_motion motion;
    struct proto_fix fix;
    struct proto_reset reset;
};

struct proto { ...; };

uint8_t proto_crc8(uint8_t crc, const uint8_t *data, uint8_t n);
void proto_init(struct proto *p);
void proto_on_write_start(struct proto *p);
void proto_on_byte(struct proto *p, uint8_t byte);
void proto_on_read_start(struct proto *p);
uint8_t proto_read_byte(struct proto *p);
void proto_on_stop(struct proto *p);
void proto_on_restart(struct proto *p);
void proto_on_abort(struct proto *p);
int proto_poll(struct proto *p, struct proto_msg *out);
void proto_publish(struct proto *p, const struct proto_snapshot *s);
uint8_t proto_status(const struct proto *p);

/* ---- physics (sim/sim.h) ---- */
struct sim_obstacle {
    uint8_t shape;
    uint8_t kind;
    double x_mm;
    double y_mm;
    double radius_mm;
    double half_x_mm;
    double half_y_mm;
    double heading_rad;
};

struct sim_line {
    double x0_mm;
    double y0_mm;
    double x1_mm;
    double y1_mm;
    double width_mm;
};

struct sim_field {
    double length_mm;
    double width_mm;
    bool borders;
    uint8_t obstacle_count;
    struct sim_obstacle obstacles[...];
    uint8_t line_count;
    struct sim_line lines[...];
};

struct sim_point { double x_mm; double y_mm; };
struct sim_pose { double x_mm; double y_mm; double heading_rad; };

struct sim_motor_config {
    double kv_rpm_per_V;
    double kt_mNm_per_A;
    double resistance_ohm;
    double inductance_mH;
    double rotor_inertia_g_cm2;
    double friction_mNm;
    double gear_ratio;
    double gear_efficiency;
    uint32_t encoder_cpr;
};

struct sim_config {
    double mass_kg;
    double yaw_inertia_kg_m2;
    double drive_weight_share;
    double friction_coeff;
    double tyre_stiffness_N_m;
    double slip_damping_N_s_m;
    double drive_radius_mm;
    double drive_track_mm;
    double wheel_inertia_g_cm2;
    struct sim_motor_config motor;
    double battery_V;
    bool lifted;
    double enc_radius_mm;
    double enc_track_mm;
    double enc_offset_x_mm;
    double enc_radius_error[2];
    double enc_track_error_mm;
    double enc_noise_mm2_per_m[2];
    uint32_t enc_cpr;
    double outline_length_mm;
    double outline_width_mm;
    double outline_offset_x_mm;
    double outline_offset_y_mm;
    uint8_t shock_count;
    struct sim_point shock[...];
    double shock_range_mm;
    bool basket_sensor;
    struct sim_point basket_sensor_pos;
    uint8_t line_sensor_count;
    struct sim_point line_sensor[...];
    double wall_stiffness_N_m;
    double wall_damping_N_s_m;
    double wall_friction_coeff;
    uint32_t substep_ns;
    uint32_t coarse_substep_ns;
    struct sim_pose start;
    uint64_t seed;
};

struct sim_truth {
    struct sim_pose pose;
    struct sim_pose odo_pose;
    double vx_mm_s;
    double vy_mm_s;
    double v_mm_s;
    double v_lateral_mm_s;
    double omega_rad_s;
    double wheel_speed_mm_s[2];
    double slip_mm_s[2];
    double current_A[2];
    double contact_force_N;
    uint64_t time_ns;
};

struct sim {
    struct sim_config cfg;
    struct sim_field field;
    uint64_t short_steps;
    uint64_t coarse_steps;
    ...;
};

struct sim_sensors {
    uint16_t enc_count[2];
    int64_t enc_total[2];
    uint16_t motor_count[2];
    int64_t motor_total[2];
    int32_t current_mA[2];
    uint8_t shock_mask;
    bool basket;
    uint8_t line_mask;
};
void sim_read_sensors(const struct sim *s, struct sim_sensors *out);

void sim_field_defaults(struct sim_field *f);
void sim_config_defaults(struct sim_config *cfg);
void sim_config_randomize(struct sim_config *cfg, uint64_t seed);
void sim_get_truth(const struct sim *s, struct sim_truth *out);
void sim_set_pose(struct sim *s, const struct sim_pose *pose);
void sim_set_battery_V(struct sim *s, double volts);
void sim_set_friction_scale(struct sim *s, int wheel, double scale);
void sim_set_motor_stuck(struct sim *s, int wheel, bool stuck);
void sim_set_encoder_cut(struct sim *s, int wheel, bool cut);
void sim_set_motor_encoder_cut(struct sim *s, int wheel, bool cut);
void sim_force_sensors(struct sim *s, uint8_t shock_mask, bool basket);
int sim_add_obstacle(struct sim *s, const struct sim_obstacle *o);
void sim_move_obstacle(struct sim *s, int i, double x_mm, double y_mm, double heading_rad);
int sim_set_opponent_path(struct sim *s, int i, const double *path_mm, int n, double speed_mm_s,
                          bool loop);

/* ---- the board on the simulator (firmware/ports/host/host.h) ---- */
struct odometry_pose { int32_t x_um; int32_t y_um; uint32_t heading_turn32; };
struct odometry_config {
    uint32_t left_um_per_count_q16;
    uint32_t right_um_per_count_q16;
    uint32_t track_um;
};
struct odometry_counter { struct odometry_config cfg; ...; };
struct uncertainty_config {
    uint32_t noise_left_mm2_per_m_q16;
    uint32_t noise_right_mm2_per_m_q16;
    uint16_t k_q8;
    uint16_t batch_ms;
};
struct uncertainty_model {
    uint32_t track_um;
    uint32_t ratio_error_ppm;
    uint32_t track_error_um;
    uint32_t scale_error_ppm;
};
struct uncertainty {
    struct uncertainty_config cfg; struct uncertainty_model model;
    uint8_t stage; /* 1..UNCERTAINTY_STAGES: a batch's, beyond: a position fix's fusion */
    ...;
};
struct control_gains { uint16_t p; uint16_t i; uint16_t d; };
struct control_config {
    int16_t duty_max_q15;
    int32_t ff_speed_q15_per_m_s;
    int32_t ff_accel_q15_per_m_s2;
    int32_t ff_angle_accel_q15_per_m_s2;
    int32_t gain_slew_q15_per_s[2];
    uint8_t d_filter_ms;
    int32_t d_lag_max_um;
    struct control_gains presets[...];
};
struct faults_config {
    uint8_t shock_basket_mask;
    int32_t following_max_um;
    uint16_t following_ms;
    int16_t current_max_ma;
    uint16_t current_ms;
    uint8_t motor_encoders;
    uint32_t motor_um_per_count_q16;
    int32_t slip_max_um;
    uint16_t slip_window_ms;
    int32_t lost_min_um;
    uint8_t repeat_max;
    uint16_t repeat_window_ms;
};
struct orders_config {
    uint32_t drive_track_um;
    uint32_t heading_window_turn32;
    int32_t freeze_radius_um;
    int32_t arrive_window_um;
    int32_t arrive_speed_um_s;
    uint16_t settle_ms;
    uint16_t settle_timeout_ms;
    int32_t push_speed_um_s;
    int32_t push_max_um;
    int32_t basket_contact_um;
    uint8_t n_baskets;
    uint8_t aim_delay_steps;
    uint32_t jerk_um_s3;
    int32_t grip_um_s2;
    uint16_t rot_grip_q8;
    int32_t front_um;
    ...;
};
struct board_unseen {
    uint32_t reach_um;
    ...;
};
struct board_residuals {
    uint32_t ratio_error_ppm;
    uint32_t track_error_um;
    uint32_t scale_error_ppm;
};
struct board_config {
    uint16_t tick_hz;
    uint8_t slow_shift;
    uint8_t planner_ticks;
    struct odometry_config odometry;
    struct uncertainty_config uncertainty;
    struct board_residuals calibrated;
    struct board_residuals uncalibrated;
    struct control_config control;
    struct faults_config faults;
    struct orders_config orders;
    struct odometry_pose start;
    uint32_t start_radius_um;
    uint32_t start_heading_bound_turn32;
    struct board_unseen unseen;
    ...;
};
struct faults {
    uint8_t cause;
    int32_t slip_dist_q16;
    int32_t lost_motor_um[2];
    int32_t lost_other_um[2];
    uint8_t lost_suspect;
    ...;
};
struct orders_axis { int32_t pos_um; int32_t vel_um_s; int32_t acc_um_s2; };
struct orders {
    uint8_t state;
    uint8_t end_reason;
    struct orders_axis sp_dist;
    struct orders_axis sp_angle;
    uint8_t give_way;
    int8_t shock_side[2];
    ...;
};
struct board_calibration { int32_t ratio_ppm; int32_t scale_ppm; uint16_t track_10um; };
struct servo {
    struct odometry_counter counter;
    struct orders_axis sp_dist;
    struct orders_axis sp_angle;
    uint16_t tick;
    uint16_t slow_overruns;
    ...;
};
struct fix_info {
    uint16_t fused;
    uint16_t outliers;
    uint16_t too_old;
    uint8_t last;
    uint8_t last_d2;
};
struct fix { struct fix_info info; ...; };
struct planner {
    struct fix fix;
    struct uncertainty uncertainty;
    struct orders orders;
    struct faults faults;
    struct control_gains gains;
    uint8_t status;
    uint8_t shocks;
    uint8_t calibrated;
    struct board_calibration calibration;
    uint8_t boot_request;
    ...;
};
struct mailbox { ...; };
struct board {
    struct board_config cfg;
    struct proto proto;
    struct servo servo;
    struct planner planner;
    struct mailbox mailbox;
    ...;
};

#define HOST_NVM_SIZE ...
struct nvm_bytes_dev {
    uint8_t mem[...];
};
struct host {
    struct sim sim;
    struct board board;
    uint64_t tick_ns;
    uint64_t ticks;
    uint64_t now_ns;
    struct nvm_bytes_dev storage;
    ...;
};

@HOST_SAMPLE@

void board_default_config(struct board_config *cfg);
void host_board_config(const struct sim_config *sc, const struct sim_field *f,
                       struct board_config *bc);
int host_init(struct host *h, const struct board_config *bc, const struct sim_config *sc,
              const struct sim_field *f);
int host_nvm_set(struct host *h, const uint8_t *data, uint16_t n);
int host_power_cycle(struct host *h);
int host_reset(struct host *h, uint8_t cause, int keep_ram, uint16_t down_ms);
uint64_t host_advance_ns(struct host *h, uint64_t duration_ns, struct host_sample *buf,
                         uint32_t cap, uint32_t *n_out);

/* ---- a whole bus transaction in one call (PREAMBLE below) ---- */
uint32_t asim_bus_write(struct host *h, const uint8_t *data, uint32_t n, int stop,
                        uint64_t byte_ns, struct host_sample *buf, uint32_t cap);
uint32_t asim_bus_read(struct host *h, uint8_t *out, uint32_t n, uint64_t byte_ns,
                       struct host_sample *buf, uint32_t cap);

/* ---- the physics and the board apart, for a port's own lockstep (harness/stm32) ---- */
struct board_inputs {
    uint16_t free_count[2];
    uint16_t motor_count[2];
    int16_t current_ma[2];
    uint8_t shocks;
    uint8_t basket;
    uint8_t lines;
};
struct board_outputs { int16_t duty_q15[2]; };
int sim_init(struct sim *s, const struct sim_config *cfg, const struct sim_field *field);
void sim_set_duty(struct sim *s, int16_t left_q15, int16_t right_q15);
void sim_advance_ns(struct sim *s, uint64_t duration_ns);
int board_init(struct board *b, const struct board_config *cfg, const struct board_inputs *in);
int board_restart(struct board *b, const struct board_config *cfg, const struct board_inputs *in,
                  uint8_t cause, uint16_t down_ms);
void board_tick(struct board *b, const struct board_inputs *in, struct board_outputs *out);
void board_slow(struct board *b);
"""

# What Simulator.i2c_write() and i2c_read() do byte by byte (python/asserv/sim/), in one call
# into C when no timed event falls within the transaction: one byte time of the bus, then the
# board's interrupt, for the address and each byte; the trace rows of the ticks run meanwhile go
# to buf (cap rows; NULL: none kept), and the count of them is returned.
PREAMBLE = """
#include "protocol.h"
#include "sim.h"
#include "host.h"

static void asim_byte_time(struct host *h, uint64_t ns, struct host_sample *buf, uint32_t cap,
                           uint32_t *rows)
{
    while (ns > 0) {
        uint32_t k = 0;
        uint64_t done = host_advance_ns(h, ns, buf ? buf + *rows : NULL, buf ? cap - *rows : 0,
                                        buf ? &k : NULL);

        *rows += k;
        if (done == 0)
            return; /* buf is full: the caller gave too few rows (it never does) */
        ns -= done;
    }
}

uint32_t asim_bus_write(struct host *h, const uint8_t *data, uint32_t n, int stop,
                        uint64_t byte_ns, struct host_sample *buf, uint32_t cap)
{
    uint32_t rows = 0;

    asim_byte_time(h, byte_ns, buf, cap, &rows);
    proto_on_write_start(&h->board.proto);
    for (uint32_t i = 0; i < n; i++) {
        asim_byte_time(h, byte_ns, buf, cap, &rows);
        proto_on_byte(&h->board.proto, data[i]);
    }
    if (stop)
        proto_on_stop(&h->board.proto);
    return rows;
}

uint32_t asim_bus_read(struct host *h, uint8_t *out, uint32_t n, uint64_t byte_ns,
                       struct host_sample *buf, uint32_t cap)
{
    uint32_t rows = 0;

    asim_byte_time(h, byte_ns, buf, cap, &rows);
    proto_on_read_start(&h->board.proto);
    for (uint32_t i = 0; i < n; i++) {
        out[i] = proto_read_byte(&h->board.proto);
        asim_byte_time(h, byte_ns, buf, cap, &rows);
    }
    proto_on_stop(&h->board.proto);
    return rows;
}
"""


def _host_sample() -> str:
    """struct host_sample as gen_trace.py wrote it (firmware/ports/host/trace.toml), between its
    cdef markers: the one list of the trace's columns."""
    text = (PORTS / "host" / "host_sample_gen.h").read_text()
    begin, end = "/* cdef: begin */", "/* cdef: end */"
    return text[text.index(begin) + len(begin) : text.index(end)]


ffibuilder = FFI()
ffibuilder.cdef(CDEF.replace("@HOST_SAMPLE@", _host_sample()))
ffibuilder.set_source(
    "asserv_sim._core",
    PREAMBLE,
    sources=[str(s.relative_to(HERE)) for s in SOURCES],
    include_dirs=[str(i.relative_to(HERE)) for i in INCLUDES],
    # As the CMake build: C99, and no fused multiply-add so the physics gives the same bits;
    # -O3 with link-time optimisation, as bench/realtime.sh builds: the board's tick calls small
    # functions of other modules all along (the same bits: no option here relaxes IEEE rules).
    extra_compile_args=["-std=c99", "-O3", "-flto", "-Wall", "-Wextra", "-ffp-contract=off"],
    extra_link_args=["-O3", "-flto", "-ffp-contract=off"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
