"""An example optikin plugin: :class:`~optikin_routed_tendon.arm.RoutedTendonArm`, registered as ``routed_tendon``."""

from optikin_routed_tendon.arm import RoutedTendonArm

__all__ = ["RoutedTendonArm"]
