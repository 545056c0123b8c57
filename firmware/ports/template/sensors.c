/* Template port: the switches and the floor's line sensors (hal_sensors.h). All are plain
 * inputs, read every tick from the control interrupt: a port reads its pins and maps them to
 * the bits the core expects, with no interrupt of their own. */
#include "hal.h"
#include "template_port.h"

/* The eight shock switches ("capteurs de choc"), bit n = CAPTEUR_n pressed, whatever the pins'
 * polarity. Debounced by the port to at most one control period: the core ORs the ticks of a
 * planner period and stops the robot in the first period where a switch reads pressed, so a
 * debounce longer than a tick delays the stop, and a bounce that shows as a release and a press
 * again re-arms a switch the core had set aside. Which switches are on the border side or the
 * basket side is board configuration, not port code. */
uint8_t hal_shock_read(void)
{
	return 0; /* no switch pressed */
}

/* The basket contact switch at the front: 1 when closed (GOTO_PANIER ends on it and the board
 * recalibrates its pose from the basket's geometry), 0 open. */
uint8_t hal_basket_contact(void)
{
	return 0;
}

/* The line sensors under the robot, bit n = sensor n sees a line (the board configuration says
 * how many there are and where). The core takes the tick where a bit changes as the crossing,
 * at that tick's travel: sample them every tick and do not filter them over more than one tick,
 * since a delay of k ticks shifts every line the board measures by k ticks of travel. */
uint8_t hal_line_read(void)
{
	return 0; /* no line seen */
}
