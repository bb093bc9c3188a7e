"""Post-processing shared by the run summary, reports and studies: macroscopic measures of a
specimen (thesis §7.5.1) and the linear static solve of a bond network."""
