"""Groot2 for botstage runs: its wire format (``protocol``), a run's trees and machines as Groot2
sees them (``tree``), the live observer that speaks the protocol (``publisher``) and .btlog files
(``btlog``)."""
