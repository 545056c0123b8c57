/* Porting contract: switches and floor sensors. */
#ifndef ASSERV_HAL_SENSORS_H
#define ASSERV_HAL_SENSORS_H

#include <stdint.h>

/* The eight shock ("choc") switches, bit n = CAPTEUR_n pressed (debounced by the port to at most
 * one control period). Their role (border side or basket side) is board configuration.
 * May be called from an interrupt: yes. */
uint8_t hal_shock_read(void);

/* The basket contact switch at the front: 1 when closed. May be called from an interrupt: yes. */
uint8_t hal_basket_contact(void);

/* Line sensors under the robot, bit n = sensor n sees a line. May be called from an interrupt:
 * yes. */
uint8_t hal_line_read(void);

#endif
